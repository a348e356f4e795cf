"""`python3 -m stampede.report`: the command line of the diagnostics report."""

import argparse
import sys

DESCRIPTION = """\
Writes DIR/report.html, a page to open in a browser (self-contained: its PNG figures lie beside it,
nothing is fetched), with each figure's numbers in a table beside it:
  - run summary: objects, counts per status and per flag with their meanings, time per object,
    the run's options and its inputs' digests;
  - distributions of e1, e2, |e|, S/N, radius, fluxes, chi2/dof and iterations;
  - PSF leakage: <e> against the PSF's e in bins, with the fitted slope alpha and its error;
  - survey (MEDS) tables: maps of the object density and of <e> on the sky (ra, dec);
  - with --truth: the per-set shears, m and c exactly as `stampede metrics` prints them (the tables
    taken as its --fit sets in the order given), m and c in bins of S/N and of size, e against
    e_true; with metacal columns also R11/R22 and the metacal-calibrated m and c;
  - with --images: data, model and residual of the saved objects with the largest chi2.
`stampede metadetect` tables (a METADETECT HDU) get the metadetection page instead: per shear type
the detections before and after the cuts (flags 0, snr > 10, T_ratio > 1.2), the S/N and T_ratio
distributions with the cuts, detections per cell, flags; R11, R22 (with and without the S/N and
T_ratio cuts), g, and for a shear pair (the +g table, then the -g one) m and c, exactly as
`stampede metrics --metadetect PLUS --minus MINUS` prints them.
Several tables (the sets of a simulation, the tiles of a survey) are pooled. Tables are streamed in
chunks of rows, so memory does not grow with their size."""

EPILOG = """\
examples:
  stampede sim great08 --out sim --sets 4 --grid 20 --snr 20
  for k in 0 1 2 3; do stampede fit sim/set_$k.fits -o fit_$k.fits; done
  python3 -m stampede.report fit_*.fits --truth sim -o report      # then open report/report.html

  stampede fit tile.fits -o tile_fit.fits --set save_images=12,40,77
  python3 -m stampede.report tile_fit.fits --images tile_fit.images.fits -o tile_report

  stampede sim cells --out cells --cells 20 --pair
  stampede metadetect cells/cell_*.fits -o plus.fits; stampede metadetect cells/minus/cell_*.fits -o minus.fits
  python3 -m stampede.report plus.fits minus.fits -o mdet_report      # +g first; shear: cells' G1, G2

Bad input (a file that is not a result table, an empty table, the truth of another run) is an error
naming the file, and no report is written."""


def shear_pair(text):
    """--shear G1,G2: two finite numbers."""
    parts = text.split(",")
    try:
        g = tuple(float(p) for p in parts)
    except ValueError:
        g = ()
    if len(g) != 2 or not all(abs(x) < 1 for x in g):
        raise argparse.ArgumentTypeError(f"'{text}' is not a shear G1,G2 (two numbers with |g| < 1)")
    return g


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python3 -m stampede.report", description=DESCRIPTION, epilog=EPILOG,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("tables", nargs="+", metavar="RESULTS.fits",
                        help="`stampede fit` output tables, or `stampede metadetect` tables: one, or a shear pair "
                             "(+g, then -g)")
    parser.add_argument("-o", "--out", required=True, metavar="DIR",
                        help="the report's directory (created; an existing report needs --overwrite)")
    parser.add_argument("--truth", metavar="DIR_OR_FILE",
                        help="a simulation's truth: its directory (truth_K.fits, matched to each table by the set "
                             "it fitted) or, for one table, its truth file")
    parser.add_argument("--images", metavar="IMAGES.fits",
                        help="the save_images output of one of the tables (OUT.images.fits beside OUT.fits)")
    parser.add_argument("--shear", metavar="G1,G2", type=shear_pair,
                        help="a metadetect shear pair's true shear (default: keywords G1, G2 of the +g table's first "
                             "input, as `stampede metrics --metadetect`)")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing report in DIR")
    parser.add_argument("--quiet", action="store_true", help="no progress on stderr")
    args = parser.parse_args(argv)
    try:
        from .build import build_report
        from .inputs import ReportError
    except ImportError as e:  # matplotlib or the extension missing: say which, without a traceback
        print(f"stampede.report: {e} (Debian: apt-get install python3-matplotlib; the stampede module must be "
              "built)", file=sys.stderr)
        return 2

    last = {}

    def progress(path, done, total):
        if args.quiet or total < 1_000_000:
            return
        step = last.get(path, 0)
        if done >= total or done - step >= total // 10:
            last[path] = done
            print(f"stampede.report: {path}: {done}/{total} rows", file=sys.stderr)

    try:
        path = build_report(args.tables, args.out, truth=args.truth, images=args.images, overwrite=args.overwrite,
                            progress=progress, shear=args.shear)
    except ReportError as e:
        print(f"stampede.report: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("stampede.report: interrupted; no report written", file=sys.stderr)
        return 130
    print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
