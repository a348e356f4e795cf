"""Fits of numpy arrays: fit_stamps and Fitter against `stampede fit`, threads, dtypes, PSF arrays."""

import os

import numpy as np
import pytest

import stampede
from conftest import MINI, MINI_PSF, columns_equal_bitwise, grid_stamps, run_cli


# The upsampled renderer at a cheaper setting than its default (the suite's time): the equality
# tested is of the two front ends, not of the renderer's accuracy.
CHEAP_UPSAMPLED = {"renderer": "upsampled", "upsampling": 3, "n_central_pixels_to_upsample": 1}


@pytest.mark.parametrize("subset,set_file,renderer", [("nf", "set_0", {"renderer": "exact"}),
                                                       ("snr40", "set_0", {"renderer": "exact"}),
                                                       ("snr40", "set_1", CHEAP_UPSAMPLED)])
def test_batch_rows_equal_the_command_bitwise(tmp_path, subset, set_file, renderer):
    """Must-show 1: the GalSim-mini sets, noise-free and S/N 40, with both renderers: every column
    but time_us, bit for bit."""
    path = os.path.join(MINI, subset, set_file + ".fits")
    out = str(tmp_path / "fit.fits")
    opts = dict(MINI_PSF, **renderer)
    if subset == "snr40":  # the set's NOISESIG, which the command takes from its header (arrays have none)
        opts["noise_sigma"] = 1.0
    sets = [a for k, v in opts.items() for a in ("--set", f"{k}={v!r}" if isinstance(v, float) else f"{k}={v}")]
    run_cli("fit", path, "-o", out, "--quiet", "--threads", "2", *sets)
    cli = stampede.read_results(out)

    rows = stampede.fit_stamps(grid_stamps(stampede.read_image(path), 39), options=opts, threads=2, grid_nx=20)
    assert rows.dtype == cli.dtype
    assert len(rows) == 400
    assert columns_equal_bitwise(rows, cli) == []
    assert (rows["status"] == 0).mean() > 0.9  # a real fit, not a table of flags


def test_rows_identical_for_one_and_two_threads(nf_set0):
    stamps = grid_stamps(nf_set0, 39)[:64]
    opts = dict(MINI_PSF, renderer="exact")
    one = stampede.fit_stamps(stamps, options=opts, threads=1)
    two = stampede.fit_stamps(stamps, options=opts, threads=2)
    assert columns_equal_bitwise(one, two) == []


def test_fitter_rows_equal_batch_rows(nf_set0):
    stamps = grid_stamps(nf_set0, 39)[:6]
    opts = stampede.Options(MINI_PSF, renderer="exact")
    batch = stampede.fit_stamps(stamps, options=opts)
    fitter = stampede.Fitter(opts, stamp_size=39)
    for k in range(len(stamps)):
        row = fitter.fit(stamps[k], id=k)
        for name in batch.dtype.names:
            if name in ("time_us", "ix", "iy"):
                continue
            assert np.array_equal(row[name], batch[name][k], equal_nan=True), name
    one = stampede.fit_stamp(stamps[2], options=opts)
    assert one["e1"] == batch["e1"][2] and one["e2"] == batch["e2"][2]


def test_grid_numbering():
    stamps = np.zeros((7, 9, 9))
    rows = stampede.fit_stamps(stamps, grid_nx=3, first_id=100, options={"noise_sigma": 1.0})
    assert list(rows["id"]) == list(range(100, 107))
    assert list(rows["ix"]) == [0, 1, 2, 0, 1, 2, 0]
    assert list(rows["iy"]) == [0, 0, 0, 1, 1, 1, 2]
    assert set(rows["status"]) == {stampede.fit_status_names.index("no_data")}  # flat stamps


def test_other_float_dtypes_and_layouts_convert_once(nf_set0):
    """float32 (GalSim's default), Fortran order and strided views give the rows of their float64 copy."""
    stamps = grid_stamps(nf_set0, 39)[:4]
    opts = dict(MINI_PSF, renderer="exact")
    ref = stampede.fit_stamps(np.ascontiguousarray(stamps, dtype=np.float64), options=opts)
    for variant in (stamps.astype(np.float32).astype(np.float64), np.asfortranarray(stamps)):
        assert columns_equal_bitwise(stampede.fit_stamps(variant, options=opts), ref) == []
    f32 = stamps.astype(np.float32)
    assert columns_equal_bitwise(stampede.fit_stamps(f32, options=opts),
                                 stampede.fit_stamps(f32.astype(np.float64), options=opts)) == []
    big = np.zeros((8, 39, 39))
    big[::2] = stamps
    assert columns_equal_bitwise(stampede.fit_stamps(big[::2], options=opts), ref) == []
    assert stampede.fit_stamps(stamps.tolist(), options=opts)["e1"].tobytes() == ref["e1"].tobytes()


def test_psf_arrays_one_for_all_and_one_per_stamp():
    """The simulator's PSF image (PSF x pixel at pixel centres, i.e. pixel integrals of the PSF)
    recovers a noise-free set's shapes as the analytic PSF does; the same image taken as point
    samples counts the pixel twice and is visibly wrong; one PSF per stamp (all the same) gives the
    rows of the shared one. The exact renderer takes the pixel integrals as band-limited samples
    (as well as the upsampled one does), and refuses point samples (an error, not a crash)."""
    sim = stampede.simulate_great08(noise_free=True, grid=2)
    psf, e_obs = sim["psf_image"], sim["truth"]["e1_obs"]
    shared = stampede.fit_stamps(sim["stamps"], psf=psf)
    analytic = stampede.fit_stamps(sim["stamps"], options={"psf_e2": 0.05})
    assert np.all(shared["status"] == 0)
    assert np.max(np.abs(shared["e1"] - e_obs)) < 5e-5  # measured 1.8e-5; analytic 2.1e-5
    assert np.max(np.abs(analytic["e1"] - e_obs)) < 5e-5
    twice = stampede.fit_stamps(sim["stamps"], psf=psf, psf_pixel_integrated=False)
    assert np.max(np.abs(twice["e1"] - e_obs)) > 2e-3  # measured 9.3e-3

    per = stampede.fit_stamps(sim["stamps"], psf=np.repeat(psf[None], 4, axis=0))
    assert columns_equal_bitwise(shared, per) == []
    exact = stampede.fit_stamps(sim["stamps"], psf=psf, options={"renderer": "exact"})
    assert np.all(exact["status"] == 0)
    assert np.max(np.abs(exact["e1"] - e_obs)) < 5e-5  # measured 2.0e-5
    with pytest.raises(stampede.Error, match="pixel-integrated"):
        stampede.fit_stamps(sim["stamps"], psf=psf, psf_pixel_integrated=False, options={"renderer": "exact"})


def test_metacal_rows_equal_the_command_bitwise(tmp_path):
    """metacal = true from numpy: the metacal columns, every column equal to `stampede fit`'s."""
    path = os.path.join(MINI, "nf", "set_0.fits")
    stamps = grid_stamps(stampede.read_image(path), 39)[:6]
    opts = dict(MINI_PSF, renderer="exact", metacal=True)
    rows = stampede.fit_stamps(stamps, options=opts, threads=2)
    assert "R11" in rows.dtype.names and "radius_2m" in rows.dtype.names
    assert np.all((rows["R11"] > 0.2) & (rows["R11"] < 2.0))
    one = stampede.Fitter(opts, stamp_size=39).fit(stamps[3], id=3)
    assert one["R22"] == rows["R22"][3] and one["e1_1p"] == rows["e1_1p"][3]


def test_metacal_with_an_image_psf_gives_a_response():
    """A PSF array: metacal deconvolves its samples and picks a round Moffat wider than it."""
    stamps = grid_stamps(stampede.read_image(os.path.join(MINI, "nf", "set_0.fits")), 39)[:2]
    psf = stampede.read_image(os.path.join(MINI, "nf", "psf_0.fits"))
    rows = stampede.fit_stamps(stamps, psf=psf, options={"renderer": "exact", "metacal": True})
    assert np.all(rows["status"] == 0)
    assert np.all((rows["R11"] > 0.2) & (rows["R11"] < 2.0))
