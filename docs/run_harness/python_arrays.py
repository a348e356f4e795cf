#!/usr/bin/env python3
"""The stampede module's array entry points, their rows written out for a bit-for-bit comparison.

Run with PYTHONPATH naming one build's python/ folder:

  python_arrays.py GRID.fits CELL.fits OUTDIR

writes, for fit_stamps (plain, metacal wmom, metacal bd), fit_stamp (one stamp) and metadetect
(one cell image):

  OUTDIR/NAME.repr  one line per row: every field but time_us as repr() (floats as repr: the
                    shortest string that reads back to the same double, so equal text is equal bits)
  OUTDIR/NAME.npy   the structured array itself with time_us set to 0

and run_fit (the Python run over files, writing a FITS table) to OUTDIR/run_fit.fits.
"""

import os
import sys

import numpy as np

import stampede

PSF = {"psf_beta": 3.0, "psf_fwhm": 2.85, "psf_e1": 0.0, "psf_e2": 0.05}
CHEAP = {"upsampling": 2, "n_central_pixels_to_upsample": 1, "padding": 0, "minimizer_max_iterations": 20}


def grid_stamps(image, s):
    ny, nx = image.shape[0] // s, image.shape[1] // s
    return image.reshape(ny, s, nx, s).transpose(0, 2, 1, 3).reshape(-1, s, s)


def write(rows, outdir, name):
    rows = np.array(rows, copy=True)
    names = [n for n in rows.dtype.names if n != "time_us"]
    with open(os.path.join(outdir, name + ".repr"), "w") as f:
        f.write("# " + " ".join(names) + "\n")
        for r in rows:
            f.write(" ".join(repr(r[n].item() if hasattr(r[n], "item") else r[n]) for n in names) + "\n")
    if "time_us" in rows.dtype.names:
        rows["time_us"] = 0
    np.save(os.path.join(outdir, name + ".npy"), rows)


def main(grid, cell, outdir):
    os.makedirs(outdir, exist_ok=True)
    image = stampede.read_image(grid)
    stamps = grid_stamps(image, 39)[:100]  # the first 100 stamps (5 grid rows of 20)
    base = dict(PSF, **CHEAP)
    write(stampede.fit_stamps(stamps, options=base, threads=1, grid_nx=20), outdir, "fit_stamps_plain")
    write(stampede.fit_stamps(stamps, options=dict(base, metacal=True), threads=2, grid_nx=20), outdir,
          "fit_stamps_metacal_wmom")
    write(stampede.fit_stamps(stamps[:40], options=dict(base, metacal=True, metacal_model="bd"), threads=2,
                              grid_nx=20), outdir, "fit_stamps_metacal_bd")
    one = stampede.fit_stamp(stamps[7], options=base)
    with open(os.path.join(outdir, "fit_stamp.repr"), "w") as f:
        for k in sorted(one):
            if k != "time_us":
                f.write("%s %r\n" % (k, one[k]))
    md = stampede.metadetect(stampede.read_image(cell, 0), stampede.read_image(cell, "WEIGHT"),
                             stampede.read_image(cell, "PSF"), 0.25, threads=1,
                             noise=stampede.read_image(cell, "NOISE"))
    write(md, outdir, "metadetect_cell")
    stampede.run_fit(grid, output=os.path.join(outdir, "run_fit.fits"), options=base, threads=2, overwrite=True)


if __name__ == "__main__":
    main(*sys.argv[1:4])
