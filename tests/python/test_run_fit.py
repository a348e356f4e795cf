"""run_fit: the `stampede fit` run from Python, its summary, warnings and errors."""

import os
import re
import shutil
import signal
import threading
import warnings

import numpy as np
import pytest

import stampede
from conftest import DATA, MINI, MINI_PSF, columns_equal_bitwise, grid_stamps, run_cli

SET0 = os.path.join(MINI, "nf", "set_0.fits")


def test_run_writes_the_table_and_returns_the_summary(tmp_path):
    out = str(tmp_path / "fit.fits")
    calls = []
    opts = dict(MINI_PSF, renderer="exact")
    s = stampede.run_fit(SET0, output=out, options=opts, threads=2,
                         progress=lambda done, total, sec: calls.append((done, total)))
    assert s["objects"] == 400 and s["output"] == out and s["threads"] == 2
    assert sum(s["status"].values()) == 400 and s["status"].get("ok", 0) > 380
    assert s["objects_per_second"] > 0 and "400 objects" in s["report"]
    assert calls and all(t == 400 for _, t in calls)
    rows = stampede.read_results(out)
    again = stampede.fit_stamps(grid_stamps(stampede.read_image(SET0), 39), options=opts, grid_nx=20)
    assert columns_equal_bitwise(rows, again) == []
    with pytest.raises(stampede.Error, match="exists"):
        stampede.run_fit(SET0, output=out, options=opts)  # refused, not overwritten
    assert stampede.run_fit(SET0, output=out, options=opts, overwrite=True)["objects"] == 400


def test_a_recorded_psf_other_than_the_runs_is_a_warning(tmp_path):
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        stampede.run_fit(SET0, output=str(tmp_path / "f.fits"), options={"psf_e2": 0.0, "renderer": "exact"})
    assert any("records a PSF other than the run's" in str(x.message) for x in w)


def interrupted_then_resumed(tmp_path, stop):
    """A run stopped by `stop` (the progress callback, or None and a signal), then resumed: the
    exception, the rows committed before it, and the resumed table."""
    out = str(tmp_path / "f.fits")
    opts = {"renderer": "exact", "batch_size": 4, **MINI_PSF}
    with pytest.raises(BaseException) as raised:
        stampede.run_fit(SET0, output=out, options=opts, threads=1, progress=stop)
    assert not os.path.exists(out) and os.path.exists(out + ".partial") and os.path.exists(out + ".checkpoint")
    with open(out + ".checkpoint") as f:
        committed = f.read()
    resumed = stampede.run_fit(SET0, output=out, options=opts, threads=2, resume=True)
    whole = str(tmp_path / "whole.fits")
    stampede.run_fit(SET0, output=whole, options=opts, threads=2)
    assert columns_equal_bitwise(stampede.read_results(out), stampede.read_results(whole)) == []
    return raised.value, resumed, committed


def test_an_exception_in_the_progress_callback_stops_the_run_resumably(tmp_path):
    def boom(done, total, seconds):
        raise KeyError("from the callback")

    error, resumed, _ = interrupted_then_resumed(tmp_path, boom)
    assert isinstance(error, KeyError) and "from the callback" in str(error)
    assert 0 < resumed["resumed"] < 100 and resumed["resumed"] + resumed["objects"] == 400


def test_ctrl_c_stops_the_run_as_the_clis_sigint_does(tmp_path):
    # SIGINT from another thread while the run holds the calling thread, as a terminal's Ctrl-C.
    timer = threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT))
    timer.start()
    try:
        error, resumed, _ = interrupted_then_resumed(tmp_path, None)
    finally:
        timer.cancel()
    assert isinstance(error, KeyboardInterrupt)
    assert resumed["resumed"] < 400 and resumed["resumed"] + resumed["objects"] == 400


def test_argument_errors_come_before_any_work(tmp_path):
    out = tmp_path / "f.fits"
    for kwargs, error, text in [
        ({"progress": 5}, TypeError, r"run_fit\(\): progress must be callable .*int 5"),
        ({"threads": "2"}, TypeError, r"run_fit\(\): threads must be an int, not str '2'"),
        ({"threads": 10**6}, stampede.ConfigError, "threads"),
        ({"shard": ("a", 3)}, TypeError, r"run_fit\(\): shard: i must be an int, not str 'a'"),
        ({"shard": (1,)}, TypeError, r"run_fit\(\): shard must be a pair \(i, N\) of ints, not tuple \(1,\)"),
        ({"shard": "1/3"}, TypeError, r"shard must be a pair \(i, N\) of ints, not str '1/3'"),
        ({"shard": (3, 3)}, ValueError, r"shard = \(3, 3\): must have 0 <= i < N"),
        ({"resume": "no"}, TypeError, r"resume must be True or False, not str 'no'"),
        ({"catalog": 7}, TypeError, r"catalog must be a str or a path \(os.PathLike\), not int 7"),
        ({"treads": 2}, TypeError, r"unexpected keyword argument 'treads' \(it takes input, output, "),
    ]:
        with pytest.raises(error, match=text):
            stampede.run_fit(SET0, output=out, **kwargs)
        assert not os.path.exists(str(out) + ".partial") and not out.exists()
    assert stampede.run_fit(SET0, output=out, options={"renderer": "exact", **MINI_PSF}, threads=np.int64(2),
                            shard=[np.int32(0), 4])["objects"] == 100  # numpy ints and pathlib paths are fine


def test_bad_options_and_paths(tmp_path):
    with pytest.raises(stampede.ConfigError, match="unknown option 'rendrer'"):
        stampede.run_fit(SET0, options={"rendrer": "exact"})
    with pytest.raises(stampede.FitsError, match="nowhere.fits"):
        stampede.run_fit(str(tmp_path / "nowhere.fits"), output=str(tmp_path / "o.fits"))


def test_shards_merged_equal_the_whole_run(tmp_path):
    opts = dict(MINI_PSF, renderer="exact")
    whole = str(tmp_path / "whole.fits")
    stampede.run_fit(SET0, output=whole, options=opts)
    parts = [str(tmp_path / f"part{i}.fits") for i in range(3)]
    for i, p in enumerate(parts):
        assert stampede.run_fit(SET0, output=p, options=opts, shard=(i, 3))["objects"] in (133, 134)
    merged = str(tmp_path / "merged.fits")
    assert stampede.merge_shards(parts[::-1], merged)["rows"] == 400
    assert columns_equal_bitwise(stampede.read_results(merged), stampede.read_results(whole)) == []
    with pytest.raises(stampede.CatalogError, match="shard 1/3 is missing"):
        stampede.merge_shards([parts[0], parts[2]], str(tmp_path / "m2.fits"))


def test_a_meds_tile_gives_the_commands_survey_rows(tmp_path):
    tile = os.path.join(DATA, "meds-sample", "meds.fits")
    out = str(tmp_path / "meds.fits")
    s = stampede.run_fit(meds=tile, output=out, threads=2)
    assert s["objects"] == 24 and s["status"].get("ok", 0) == 24
    rows = stampede.read_results(out)
    for name in ("id", "number", "ra", "dec", "n_epochs", "masked_frac", "psf_size", "is_bulge"):
        assert name in rows.dtype.names
    assert (rows["n_epochs"] == 4).all() and (rows["is_bulge"] == -1).all()
    assert np.isnan(rows["other_likelihood"]).all()  # bd: no losing model
    cli = str(tmp_path / "cli.fits")
    run_cli("fit", "--meds", tile, "-o", cli, "--quiet")
    assert columns_equal_bitwise(rows, stampede.read_results(cli)) == []
    with pytest.raises(stampede.Error, match="takes no INPUT"):
        stampede.run_fit(os.path.join(MINI, "nf", "set_0.fits"), meds=tile, output=str(tmp_path / "x.fits"))


def test_meds_tiles_of_several_bands_are_fitted_jointly(tmp_path):
    sim = str(tmp_path / "sim")
    run_cli("sim", "meds", "--out", sim, "--bands", "g,r", "--objects", "6", "--epochs", "2", "--snr", "30")
    tiles = [os.path.join(sim, b, "meds.fits") for b in ("g", "r")]
    out = str(tmp_path / "bands.fits")
    s = stampede.run_fit(meds=tiles, bands=["g", "r"], output=out, threads=2)
    assert s["objects"] == 6
    rows = stampede.read_results(out)
    for name in ("n_epochs_g", "flux_g", "bulge_flux_r", "disc_flux_r", "snr_r"):
        assert name in rows.dtype.names
    assert (rows["n_epochs_g"] == 2).all() and (rows["n_epochs"] == 4).all()
    assert np.allclose(rows["flux"], rows["flux_g"] + rows["flux_r"], rtol=1e-12)
    assert np.allclose(rows["snr"] ** 2, rows["snr_g"] ** 2 + rows["snr_r"] ** 2, rtol=1e-9)
    cli = str(tmp_path / "cli.fits")
    run_cli("fit", "--meds", tiles[0], "--meds", tiles[1], "--bands", "g,r", "-o", cli, "--quiet")
    assert columns_equal_bitwise(rows, stampede.read_results(cli)) == []
    # metacal wmom measures one set of moments over every band's cutouts: its flux is a weighted mean
    # of the bands' (not their sum, which the docs promised), its snr that measurement's, at most the
    # bands' quadrature sum.
    mcal = str(tmp_path / "wmom.fits")
    stampede.run_fit(meds=tiles, bands=["g", "r"], output=mcal, options={"metacal": True}, threads=2)
    m = stampede.read_results(mcal)
    low, high = np.minimum(m["flux_g"], m["flux_r"]), np.maximum(m["flux_g"], m["flux_r"])
    assert ((m["flux"] >= low) & (m["flux"] <= high)).all(), (m["flux"], m["flux_g"], m["flux_r"])
    assert (m["snr"] <= np.hypot(m["snr_g"], m["snr_r"]) * (1 + 1e-12)).all()
    with pytest.raises(stampede.ConfigError, match="names 1 bands for 2 --meds tiles"):
        stampede.run_fit(meds=tiles, bands=["g"], output=str(tmp_path / "x.fits"))
    with pytest.raises(TypeError, match="bands"):
        stampede.run_fit(meds=tiles, bands="gr", output=str(tmp_path / "x.fits"))
    # FITS column lookup ignores case: flux_G and flux_g would be one column to every reader.
    with pytest.raises(ValueError, match=r"run_fit\(\): bands: bands 'G' and 'g' differ only in case"):
        stampede.run_fit(meds=tiles, bands=["G", "g"], output=str(tmp_path / "x.fits"))
    # The same tile as two bands (here a copy) would count its pixels twice: S/N sqrt(2) too high.
    copy = str(tmp_path / "copy.fits")
    shutil.copyfile(tiles[0], copy)
    with pytest.raises(stampede.ConfigError, match=re.escape(f"'{copy}' (band r) holds the same bytes as --meds '{tiles[0]}' (band g)")):
        stampede.run_fit(meds=[tiles[0], copy], bands=["g", "r"], output=str(tmp_path / "x.fits"))
    assert not os.path.exists(tmp_path / "x.fits")


def test_bord_rows_hold_the_losing_models_likelihood(tmp_path):
    # Issue 31: the docs promised the loser's likelihood and no column held it.
    tile = os.path.join(DATA, "meds-sample", "meds.fits")
    out = str(tmp_path / "bord.fits")
    stampede.run_fit(meds=tile, output=out, options={"meds_model": "bord"}, shard=(0, 6), threads=2)
    rows = stampede.read_results(out)
    assert len(rows) == 4 and set(rows["is_bulge"]) <= {0, 1}
    assert np.isfinite(rows["other_likelihood"]).all()
    assert (rows["likelihood"] >= rows["other_likelihood"]).all()
    assert (rows["likelihood"] != rows["other_likelihood"]).any()


def test_an_empty_list_of_tiles_is_refused_by_name(tmp_path):
    """meds=[] used to end in "cannot open FITS file ''"; an empty path in the list likewise."""
    out = tmp_path / "o.fits"
    with pytest.raises(ValueError, match=r"run_fit\(\): meds is an empty list: give a MEDS tile's path"):
        stampede.run_fit(meds=[], output=out)
    with pytest.raises(ValueError, match=r"run_fit\(\): meds\[1\] is an empty path"):
        stampede.run_fit(meds=[os.path.join(DATA, "meds-sample", "meds.fits"), ""], output=out)
    assert not out.exists() and not os.path.exists(str(out) + ".partial")


def test_resuming_a_complete_output_leaves_it_as_it_is(tmp_path):
    """resume=True on an output this run finished: 'skipped', the file untouched (it used to raise
    "'OUT.checkpoint' does not exist"); another run's complete output is refused."""
    out = tmp_path / "done.fits"
    opts = dict(MINI_PSF, renderer="exact")
    assert stampede.run_fit(SET0, output=out, options=opts, shard=(0, 8))["skipped"] is False
    before = (out.read_bytes(), os.stat(out).st_mtime_ns)
    again = stampede.run_fit(SET0, output=out, options=opts, shard=(0, 8), resume=True)
    assert again["skipped"] is True and again["objects"] == 0
    assert (out.read_bytes(), os.stat(out).st_mtime_ns) == before
    with pytest.raises(stampede.ConfigError, match="is complete but was written by another run"):
        stampede.run_fit(SET0, output=out, options=dict(opts, minimizer_max_iterations=3), shard=(0, 8), resume=True)


def test_a_moments_weight_narrower_than_gamma_is_refused_or_flagged(tmp_path):
    """metacal_weight_fwhm below the reconvolution PSF's FWHM: on a MEDS tile (0.1 arcsec) R11 read
    16.6 with status ok. A grid run, whose Gamma is known up front, refuses it; a MEDS run, whose
    Gamma is per object, flags the rows metacal failures (excluded from shear)."""
    with pytest.raises(stampede.ConfigError, match="metacal_weight_fwhm = 1 is narrower than the reconvolution PSF"):
        stampede.run_fit(SET0, output=str(tmp_path / "grid.fits"),
                         options=dict(MINI_PSF, metacal=True, metacal_weight_fwhm=1.0), shard=(0, 8))
    sim = str(tmp_path / "sim")
    run_cli("sim", "meds", "--out", sim, "--objects", "4", "--epochs", "2", "--snr", "30")
    out = str(tmp_path / "meds.fits")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        stampede.run_fit(meds=os.path.join(sim, "meds.fits"), output=out, threads=2,
                         options={"metacal": True, "metacal_weight_fwhm": 0.1})
    rows = stampede.read_results(out)
    assert (rows["flags"] & 262144).all() and (rows["status"] != 0).all()
    assert any("metacal_weight_fwhm = 0.1 is narrower than the reconvolution PSF's FWHM" in str(w.message)
               for w in caught), [str(w.message) for w in caught]
    ok = str(tmp_path / "ok.fits")
    stampede.run_fit(meds=os.path.join(sim, "meds.fits"), output=ok, threads=2, options={"metacal": True})
    assert (stampede.read_results(ok)["status"] == 0).all()
