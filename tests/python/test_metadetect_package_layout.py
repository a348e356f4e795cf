"""The reference metadetect package's layout (issue 56, must-show 4): `stampede metadetect
--package-output` read back with stampede.read_package_layout, and stampede.metadetect(...,
layout="package") over several bands' arrays, give one structured array per shear type with the
package's column names; the package's own shear-test estimator, written against those names, gives
the response and m that `stampede metrics --metadetect` gives for the same tables. Mask bits are
reported per detection; bad masks are errors naming themselves."""

import os
import subprocess

import numpy as np
import pytest

import stampede
from conftest import CLI, run_cli

SHEAR_TYPES = ["noshear", "1p", "1m", "2p", "2m"]
STEP = 0.01


# --- The package's shear-test estimator, as analysis code written for its output has it --------
def _shear_cuts(arr, model):
    return (arr[f"{model}_flags"] == 0) & (arr[f"{model}_s2n"] > 10) & (arr[f"{model}_T_ratio"] > 1.2)


def _meas_shear_data(res, model):
    """g1, g2 of noshear and R11, R22 from 1p/1m, 2p/2m of one cell's result dict."""
    msk = _shear_cuts(res["noshear"], model)
    g1, g2 = np.mean(res["noshear"][f"{model}_g"][msk, 0]), np.mean(res["noshear"][f"{model}_g"][msk, 1])
    means = {}
    for t in ("1p", "1m", "2p", "2m"):
        m = _shear_cuts(res[t], model)
        means[t] = np.mean(res[t][f"{model}_g"][m, 0 if t[0] == "1" else 1])
    return g1, g2, (means["1p"] - means["1m"]) / (2 * STEP), (means["2p"] - means["2m"]) / (2 * STEP)


def _m_c(plus, minus, model, shear=0.02):
    """m, c over cells: <g1+ - g1-> / 2 / <R11+ + R11-> / 2 / shear - 1, c from g2 the same way."""
    p = np.array([_meas_shear_data(r, model) for r in plus])
    q = np.array([_meas_shear_data(r, model) for r in minus])
    m = np.mean(p[:, 0] - q[:, 0]) / 2 / (np.mean(p[:, 2] + q[:, 2]) / 2) / shear - 1
    c = np.mean(p[:, 1] + q[:, 1]) / 2 / (np.mean(p[:, 3] + q[:, 3]) / 2)
    return m, c, np.mean(p[:, 2])


def _per_cell(res):
    """Our file holds every cell: split it into the per-cell dicts the package returns."""
    cells = np.unique(res["noshear"]["cell"])
    return [{t: res[t][res[t]["cell"] == k] for t in SHEAR_TYPES} for k in cells]
# ------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    d = str(tmp_path_factory.mktemp("pair"))
    run_cli("sim", "cells", "--out", d, "--cells", "4", "--pair", "--snr", "1e4", "--seed", "5")
    out = {}
    for sign, sub in (("plus", ""), ("minus", "minus/")):
        table, package = os.path.join(d, sign + ".fits"), os.path.join(d, sign + "_package.fits")
        run_cli("metadetect", *[os.path.join(d, sub + "cell_%04d.fits" % k) for k in range(4)],
                "-o", table, "--package-output", package, "--quiet")
        out[sign] = (table, package)
    return out


def test_package_layout_file_has_the_package_columns(pair):
    res = stampede.read_package_layout(pair["plus"][1])
    assert list(res) == SHEAR_TYPES
    names = res["noshear"].dtype.names
    for name in ["wmom_flags", "wmom_psf_flags", "wmom_psf_g", "wmom_psf_T", "wmom_obj_flags", "wmom_s2n", "wmom_g",
                 "wmom_g_cov", "wmom_T", "wmom_T_flags", "wmom_T_err", "wmom_T_ratio", "wmom_band_flux_flags",
                 "wmom_band_flux", "wmom_band_flux_err", "shear_bands", "sx_row", "sx_col", "sx_row_noshear",
                 "sx_col_noshear", "ormask", "mfrac", "bmask", "det_bands", "psfrec_flags", "psfrec_g", "psfrec_T"]:
        assert name in names, name
    ns = res["noshear"]
    assert ns["wmom_g"].shape == (len(ns), 2) and ns["wmom_g_cov"].shape == (len(ns), 2, 2)
    assert len(ns) == 4 * 49  # a 7 x 7 grid per cell, every galaxy once
    # The values are our table's, row for row.
    table = stampede.read_table(pair["plus"][0], "METADETECT", ["shear_type", "e1", "e2", "e1_err", "snr", "T_ratio",
                                                                 "x", "y", "x_noshear", "psf_orig_e1"])
    for t in SHEAR_TYPES:
        sel = table["shear_type"] == t
        assert np.array_equal(res[t]["wmom_g"][:, 0], table["e1"][sel])
        assert np.array_equal(res[t]["wmom_g"][:, 1], table["e2"][sel])
        assert np.array_equal(res[t]["wmom_g_cov"][:, 0, 0], table["e1_err"][sel] ** 2)
        assert np.all(res[t]["wmom_g_cov"][:, 0, 1] == 0)
        assert np.array_equal(res[t]["wmom_s2n"], table["snr"][sel])
        assert np.array_equal(res[t]["wmom_T_ratio"], table["T_ratio"][sel])
        assert np.array_equal(res[t]["sx_col"], table["x"][sel].astype(np.float32))
        assert np.array_equal(res[t]["sx_row"], table["y"][sel].astype(np.float32))
        assert np.array_equal(res[t]["sx_col_noshear"], table["x_noshear"][sel].astype(np.float32))
        assert np.array_equal(res[t]["psfrec_g"][:, 0], table["psf_orig_e1"][sel])
    # noshear is not sheared: its positions are their own unsheared ones; 1p moves x by ~step x (x - centre).
    assert np.allclose(res["noshear"]["sx_col_noshear"], res["noshear"]["sx_col"], atol=1e-3)
    c = 125.0
    moved = res["1p"]["sx_col"] - res["1p"]["sx_col_noshear"]
    assert np.allclose(moved, STEP * (res["1p"]["sx_col_noshear"] - c), atol=0.02)


def test_package_estimator_on_our_output_gives_our_metrics(pair):
    plus = _per_cell(stampede.read_package_layout(pair["plus"][1]))
    minus = _per_cell(stampede.read_package_layout(pair["minus"][1]))
    assert len(plus) == len(minus) == 4
    m, c, r11 = _m_c(plus, minus, "wmom")
    ours = stampede.metadetect_metrics(pair["plus"][0], minus=pair["minus"][0], estimator="package", cut_mfrac=1.0)
    assert abs(r11 - ours["R11"]) < 1e-12 * abs(ours["R11"]) + 1e-14
    assert abs(m - ours["m1"]) < 1e-9
    assert abs(c - ours["c2"]) < 1e-9
    assert abs(m) < 3e-3  # S/N 1e4 grid cells: the shear is recovered


@pytest.fixture(scope="module")
def bands(tmp_path_factory):
    d = str(tmp_path_factory.mktemp("bands"))
    run_cli("sim", "cells", "--out", d, "--cells", "1", "--snr", "1e4", "--bands", "g,r,i")
    paths = [os.path.join(d, b, "cell_0000.fits") for b in "gri"]
    arrays = {hdu: [stampede.read_image(p, hdu) for p in paths] for hdu in (0, "WEIGHT", "PSF", "NOISE")}
    return d, paths, arrays


def test_python_call_over_several_bands_returns_the_package_layout(bands, tmp_path):
    d, paths, a = bands
    res = stampede.metadetect(a[0], a["WEIGHT"], a["PSF"], 0.25, noise=a["NOISE"], layout="package",
                              detect_bands=[0, 1, 2], shear_bands=[1, 2], threads=2)
    assert list(res) == SHEAR_TYPES
    ns = res["noshear"]
    assert ns["wmom_band_flux"].shape == (len(ns), 3)
    assert set(ns["shear_bands"]) == {"12"} and set(ns["det_bands"]) == {"012"}
    # The same as the command line's file for the same bands and roles.
    package = str(tmp_path / "package.fits")
    run_cli("metadetect", os.path.join(d, "{band}", "cell_0000.fits"), "--bands", "g,r,i", "--shear-bands", "r,i",
            "-o", str(tmp_path / "table.fits"), "--package-output", package, "--quiet")
    cli = stampede.read_package_layout(package)
    for t in SHEAR_TYPES:
        assert len(res[t]) == len(cli[t])
        for name in res[t].dtype.names:
            x, y = res[t][name], cli[t][name]
            if x.dtype.kind == "U":
                assert np.array_equal(x, y), name
            else:
                assert np.array_equal(x.astype(np.float64), y.astype(np.float64), equal_nan=True), (t, name)
    # Fluxes per band: band b of the simulation is (1 + 0.5 b / 2) x the first band's.
    good = (ns["wmom_flags"] == 0) & (ns["wmom_s2n"] > 100)
    ratio = ns["wmom_band_flux"][good, 2] / ns["wmom_band_flux"][good, 0]
    assert np.all(np.abs(ratio / 1.5 - 1) < 0.1)


def test_mask_bits_are_reported_at_each_detection_and_flagged(bands):
    _, _, a = bands
    image, weight, psf = a[0][0], a["WEIGHT"][0], a["PSF"][0]
    bmask = np.zeros(image.shape, dtype=np.int32)
    ormask = np.zeros(image.shape, dtype=np.int32)
    bmask[100:151, 100:151] = 8  # a bad region over the middle galaxies: masked, its bit reported
    ormask[:, :125] = 1 << 5  # a bit that masks nothing, over the left half
    rows = stampede.metadetect(image, weight, psf, 0.25, bmask=bmask, ormask=ormask, threads=2)
    ok = rows["id"] >= 0
    x, y = np.rint(rows["x_noshear"][ok]).astype(int), np.rint(rows["y_noshear"][ok]).astype(int)
    assert np.array_equal(rows["bmask"][ok], bmask[y, x])
    assert np.array_equal(rows["ormask"][ok], ormask[y, x])
    inside = rows["bmask"][ok] == 8
    assert inside.any() and (~inside).any()
    assert np.all(rows["flags"][ok][inside] & 4)  # the detection's own pixel is masked
    assert np.any(rows["ormask"][ok] == 32) and np.any(rows["ormask"][ok] == 0)
    # An mfrac plane is what mfrac averages: a uniform 0.25 gives 0.25 to every row (each >= 34 px
    # inside the cell, beyond the Gaussian's reach of its edge).
    uniform = stampede.metadetect(image, weight, psf, 0.25, mfrac=np.full(image.shape, 0.25), threads=2)
    assert np.allclose(uniform["mfrac"][uniform["id"] >= 0], 0.25, rtol=0, atol=1e-12)
    package = stampede.metadetect(image, weight, psf, 0.25, bmask=bmask, ormask=ormask, threads=2, layout="package")
    assert np.array_equal(package["noshear"]["bmask"], rows["bmask"][rows["shear_type"] == "noshear"])


def test_bad_masks_and_star_catalogues_are_errors_naming_them(bands, tmp_path):
    d, paths, a = bands
    image, weight, psf = a[0][0], a["WEIGHT"][0], a["PSF"][0]
    with pytest.raises(ValueError, match="bmask.*shape"):
        stampede.metadetect(image, weight, psf, 0.25, bmask=np.zeros((10, 10)))
    with pytest.raises(ValueError, match="ormask.*2 bands, the image 3"):
        stampede.metadetect(a[0], a["WEIGHT"], a["PSF"], 0.25, ormask=[np.zeros(image.shape)] * 2)
    bad = np.zeros(image.shape)
    bad[3, 4] = np.nan
    with pytest.raises(ValueError, match=r"mfrac.*masked fraction nan at pixel \(4, 3\)"):
        stampede.metadetect(image, weight, psf, 0.25, mfrac=bad)
    with pytest.raises(ValueError, match="shear_bands"):
        stampede.metadetect(a[0], a["WEIGHT"], a["PSF"], 0.25, shear_bands=[3])
    with pytest.raises(ValueError, match="layout.*table or package"):
        stampede.metadetect(image, weight, psf, 0.25, layout="fits")
    # An image given as the star catalogue: refused naming the file, before anything is written.
    bad = subprocess.run([CLI, "metadetect", paths[0], "-o", str(tmp_path / "o.fits"), "--star-mask", paths[1]],
                         capture_output=True, text=True)
    assert bad.returncode != 0 and paths[1] in bad.stderr, bad.stderr
    assert not os.path.exists(str(tmp_path / "o.fits"))
