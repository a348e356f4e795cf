"""stampede.report: the diagnostics of a run as a page a person opens in a browser.

    python3 -m stampede.report RESULTS.fits [MORE.fits ...] -o DIR [--truth DIR_OR_FILE] [--images IMAGES.fits]
    python3 -m stampede.report PLUS.fits [MINUS.fits] -o DIR [--shear G1,G2]   (`stampede metadetect` tables)

writes DIR/report.html and its PNG figures (see `python3 -m stampede.report --help` and
docs/report/README.md). From Python: stampede.report.build_report(tables, out_dir, truth=None,
images=None, overwrite=False, shear=None).

Files, one concept each: fits_file (FITS headers, tables in row chunks and images, read by the
C++ io layer through stampede.fits_header and read_table), inputs (result tables, truth and
save_images files, checked), statistics (streaming accumulators), shear (m and c against the
truth, through stampede.set_shear and shear_metrics), metadetect (the metadetection page, its
numbers by stampede.metadetect_metrics), figures (matplotlib), page (HTML), build
(the whole report, written atomically), __main__ (the command).
"""

from .build import build_report  # noqa: F401
from .inputs import ReportError  # noqa: F401

__all__ = ["build_report", "ReportError"]
