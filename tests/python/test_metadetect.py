"""stampede.metadetect on numpy arrays: the rows equal `stampede metadetect`'s on the same image
(with its NOISE plane as fixnoise's field, or without: a field drawn from the weight), a cell of a
grid finds every galaxy once per image, pgauss's rows equal the command line's too, detect()
finds the grid with our detector and SEP's alike, and bad arguments are errors naming them."""

import os

import numpy as np
import pytest

import stampede
from conftest import run_cli


@pytest.fixture(scope="module")
def cell(tmp_path_factory):
    d = tmp_path_factory.mktemp("cells")
    run_cli("sim", "cells", "--out", str(d), "--cells", "1", "--snr", "1e4")
    path = os.path.join(str(d), "cell_0000.fits")
    return path, stampede.read_image(path, 0), stampede.read_image(path, "WEIGHT"), stampede.read_image(path, "PSF")


COLUMNS = ["cell", "id", "x", "y", "e1", "e2", "T", "T_ratio", "snr", "flux", "flags"]


def test_rows_equal_the_command_line_run(cell, tmp_path):
    path, image, weight, psf = cell
    rows = stampede.metadetect(image, weight, psf, 0.25, threads=2, noise=stampede.read_image(path, "NOISE"))
    assert len(rows) == 5 * 49
    assert sorted(set(rows["shear_type"])) == ["1m", "1p", "2m", "2p", "noshear"]
    assert np.all(rows["flags"] == 0)
    out = str(tmp_path / "out.fits")
    run_cli("metadetect", path, "-o", out, "--quiet")
    table = stampede.read_table(out, "METADETECT", COLUMNS)
    for name in COLUMNS:
        assert np.array_equal(np.asarray(rows[name], dtype=table[name].dtype), table[name]), name


def test_without_the_noise_plane_rows_equal_a_run_that_draws_the_field(cell, tmp_path):
    path, image, weight, psf = cell
    rows = stampede.metadetect(image, weight, psf, 0.25)
    out = str(tmp_path / "drawn.fits")
    run_cli("metadetect", path, "-o", out, "--quiet", "--no-noise-plane")
    table = stampede.read_table(out, "METADETECT", COLUMNS)
    for name in COLUMNS:
        assert np.array_equal(np.asarray(rows[name], dtype=table[name].dtype), table[name]), name
    # The file's own NOISE plane is another field: other rows.
    with_plane = stampede.metadetect(image, weight, psf, 0.25, noise=stampede.read_image(path, "NOISE"))
    assert not np.array_equal(with_plane["e1"], rows["e1"])


def test_pgauss_rows_equal_the_command_line_run(cell, tmp_path):
    path, image, weight, psf = cell
    rows = stampede.metadetect(image, weight, psf, 0.25, measurement="pgauss",
                               noise=stampede.read_image(path, "NOISE"))
    out = str(tmp_path / "pgauss.fits")
    run_cli("metadetect", path, "-o", out, "--quiet", "--measurement", "pgauss")
    table = stampede.read_table(out, "METADETECT", COLUMNS)
    for name in COLUMNS:
        assert np.array_equal(np.asarray(rows[name], dtype=table[name].dtype), table[name]), name
    wmom = stampede.metadetect(image, weight, psf, 0.25, noise=stampede.read_image(path, "NOISE"))
    assert not np.array_equal(wmom["e1"], rows["e1"])


def test_bad_arguments_name_themselves(cell):
    _, image, weight, psf = cell
    with pytest.raises(ValueError, match="weight"):
        stampede.metadetect(image, weight[:10], psf, 0.25)
    for scale in (0.0, float("inf"), float("nan")):
        with pytest.raises(ValueError, match="pixel_scale"):
            stampede.metadetect(image, weight, psf, scale)
    with pytest.raises(ValueError, match="psf"):
        stampede.metadetect(image, weight, np.zeros((5, 5)), 0.25)
    # A PSF image with no middle pixel, or not centred there, would move every position.
    with pytest.raises(ValueError, match="psf.*sides must be odd"):
        stampede.metadetect(image, weight, psf[:-1, :], 0.25)
    with pytest.raises(ValueError, match="psf.*centroid is"):
        stampede.metadetect(image, weight, np.roll(psf, 2, axis=1), 0.25)
    # A NOISE plane that is not the weights' noise.
    with pytest.raises(ValueError, match="noise.*rms is"):
        stampede.metadetect(image, weight, psf, 0.25, noise=100 / np.sqrt(weight))
    with pytest.raises(stampede.ConfigError, match="smaller than one cell"):
        stampede.metadetect(image[:100, :100], weight[:100, :100], psf, 0.25)
    # Python is told the keyword it gave, not a command-line flag.
    with pytest.raises(stampede.ConfigError, match="^cell_buffer = 200: "):
        stampede.metadetect(image, weight, psf, 0.25, cell_buffer=200)
    with pytest.raises(ValueError, match="noise"):
        stampede.metadetect(image, weight, psf, 0.25, noise=weight[:10])
    with pytest.raises(ValueError, match="measurement"):
        stampede.metadetect(image, weight, psf, 0.25, measurement="ksigma")
    with pytest.raises(TypeError, match="unknown_option"):
        stampede.metadetect(image, weight, psf, 0.25, unknown_option=1)


def test_masked_cell_is_one_flagged_row(cell):
    _, image, weight, psf = cell
    rows = stampede.metadetect(image, np.zeros_like(weight), psf, 0.25)
    assert len(rows) == 1
    assert rows["id"][0] == -1
    assert rows["flags"][0] == 8


def test_metrics_of_a_shear_pair(tmp_path):
    d = str(tmp_path)
    run_cli("sim", "cells", "--out", d, "--cells", "3", "--pair", "--snr", "1e4")
    for sign, sub in (("plus", ""), ("minus", "minus/")):
        run_cli("metadetect", *[os.path.join(d, sub + "cell_%04d.fits" % k) for k in range(3)],
                "-o", os.path.join(d, sign + ".fits"), "--quiet")
    r = stampede.metadetect_metrics(os.path.join(d, "plus.fits"), minus=os.path.join(d, "minus.fits"))
    assert r["cells"] == 3 and r["pairs"] == 3
    assert r["shear"] == (0.02, 0.0)
    assert 0.35 < r["R11"] < 0.45  # wmom under 1.2", the Gaussian reconvolution PSF
    assert abs(r["m1"]) < 3e-3
    assert r["estimator"] == "composed"
    package = stampede.metadetect_metrics(os.path.join(d, "plus.fits"), minus=os.path.join(d, "minus.fits"),
                                          estimator="package")
    # The package's estimator reads |g| high by |g|^2: m larger by 4.0e-4 at g = 0.02.
    assert abs(package["m1"] - r["m1"] - 0.02 ** 2 * (1 + package["m1"])) < 2e-5
    given = stampede.metadetect_metrics(os.path.join(d, "plus.fits"), minus=os.path.join(d, "minus.fits"),
                                        shear=[0.02, 0.0])
    assert given["m1"] == r["m1"]


def test_detect_finds_the_grid_with_either_detector(cell):
    path, image, weight, _ = cell
    sigma = 1 / np.sqrt(np.median(weight))
    ours = stampede.detect(image, sigma)
    sep = stampede.detect(image, sigma, detector="sep")
    assert len(ours["x"]) == len(sep["x"]) >= 49
    order = np.lexsort((ours["x"], ours["y"])), np.lexsort((sep["x"], sep["y"]))
    assert np.allclose(ours["x"][order[0]], sep["x"][order[1]], atol=1e-5)
    assert np.allclose(ours["y"][order[0]], sep["y"][order[1]], atol=1e-5)
    assert np.array_equal(ours["sep_flags"][order[0]], sep["sep_flags"][order[1]])
    bright = ours["flux"] > 0.5 * np.max(ours["flux"])
    assert bright.sum() == 49
    with pytest.raises(ValueError, match="detector"):
        stampede.detect(image, sigma, detector="sextractor")
    with pytest.raises(ValueError, match="sigma"):
        stampede.detect(image, 0.0)
    with pytest.raises(ValueError, match="detect: detect_min_area = 0"):  # the keyword, not a flag
        stampede.detect(image, sigma, detect_min_area=0)
