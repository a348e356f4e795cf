"""run_fit: the `stampede fit` run from Python, its summary, warnings and errors."""

import os
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


def test_an_exception_in_the_progress_callback_is_raised_after_the_run(tmp_path):
    def boom(done, total, seconds):
        raise KeyError("from the callback")

    with pytest.raises(KeyError, match="from the callback"):
        stampede.run_fit(SET0, output=str(tmp_path / "f.fits"), options={"renderer": "exact"}, progress=boom)


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
    cli = str(tmp_path / "cli.fits")
    run_cli("fit", "--meds", tile, "-o", cli, "--quiet")
    assert columns_equal_bitwise(rows, stampede.read_results(cli)) == []
    with pytest.raises(stampede.Error, match="takes no INPUT"):
        stampede.run_fit(os.path.join(MINI, "nf", "set_0.fits"), meds=tile, output=str(tmp_path / "x.fits"))
