"""Must-show 3: bad arrays are a Python exception or a flagged row, never a crash."""

import math
import os

import numpy as np
import pytest

import stampede
from conftest import MINI

STATUS = stampede.fit_status_names
OPTS = {"renderer": "exact", "psf_e2": 0.05}


@pytest.fixture(scope="module")
def stamps():
    return stampede.simulate_great08(grid=2, snr=40)["stamps"]


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_pixels_flag_the_row(stamps, bad):
    s = stamps.copy()
    s[1, 10, 12] = bad
    rows = stampede.fit_stamps(s, options=OPTS)
    assert STATUS[rows["status"][1]] == "bad_pixels"
    assert [STATUS[v] for v in rows["status"][[0, 2, 3]]] == ["ok"] * 3  # its neighbours are fitted
    assert STATUS[stampede.Fitter(OPTS).fit(s[1])["status"]] == "bad_pixels"


def test_all_nan_stamp_flags_the_row(stamps):
    s = stamps.copy()
    s[0] = np.nan
    assert STATUS[stampede.fit_stamps(s, options=OPTS)["status"][0]] == "bad_pixels"


def test_negative_or_nan_weights_flag_the_row(stamps):
    w = np.ones_like(stamps)
    w[2, 0, 0] = -1.0
    w[3, 5, 5] = np.nan
    rows = stampede.fit_stamps(stamps, weights=w, options=OPTS)
    assert [STATUS[v] for v in rows["status"]] == ["ok", "ok", "bad_pixels", "bad_pixels"]
    assert STATUS[stampede.fit_stamp(stamps[2], weight=w[2], options=OPTS)["status"]] == "bad_pixels"


@pytest.mark.parametrize("shape", [(39,), (1, 2, 39, 39), ()])
def test_wrong_number_of_dimensions(shape):
    with pytest.raises(ValueError, match="stamps must be a 3-D array"):
        stampede.fit_stamps(np.zeros(shape))
    with pytest.raises(ValueError, match="stamp must be a 2-D array"):
        stampede.fit_stamp(np.zeros(shape))


def test_non_square_and_empty():
    with pytest.raises(ValueError, match="stamps must be square, not 39 x 40"):
        stampede.fit_stamps(np.zeros((2, 39, 40)))
    with pytest.raises(ValueError, match="stamp must be square"):
        stampede.Fitter().fit(np.zeros((39, 38)))
    with pytest.raises(ValueError, match="is empty"):
        stampede.fit_stamps(np.zeros((0, 39, 39)))
    with pytest.raises(ValueError, match="this Fitter's stamps 39 x 39"):
        stampede.Fitter(stamp_size=39).fit(np.zeros((25, 25)))


@pytest.mark.parametrize("dtype", [np.int64, np.int16, np.uint8, bool, np.complex128, object, "U3"])
def test_wrong_dtypes_are_type_errors(dtype):
    a = np.ones((2, 9, 9)).astype(dtype)
    with pytest.raises(TypeError, match="stamps must hold floating-point values, not dtype"):
        stampede.fit_stamps(a)
    with pytest.raises(TypeError, match="weights must hold floating-point values"):
        stampede.fit_stamps(np.ones((2, 9, 9)), weights=a)
    with pytest.raises(TypeError, match="psf must hold floating-point values"):
        stampede.fit_stamps(np.ones((2, 9, 9)), psf=a[0])


def test_ragged_lists_are_errors_not_crashes():
    with pytest.raises((ValueError, TypeError)):
        stampede.fit_stamps([[[1.0, 2.0]], [[1.0]]])


def test_non_contiguous_views_are_fitted_as_their_copies(stamps):
    view = np.swapaxes(np.swapaxes(stamps, 1, 2).copy(), 1, 2)  # the same values, strided in memory
    assert not view.flags["C_CONTIGUOUS"]
    a = stampede.fit_stamps(view, options=OPTS)
    b = stampede.fit_stamps(np.ascontiguousarray(view), options=OPTS)
    assert a["e1"].tobytes() == b["e1"].tobytes() and a["chi2"].tobytes() == b["chi2"].tobytes()


def test_weights_psf_and_argument_shapes():
    s = np.ones((3, 15, 15))
    with pytest.raises(ValueError, match=r"weights have shape \(3, 15, 14\), the stamps \(3, 15, 15\)"):
        stampede.fit_stamps(s, weights=np.ones((3, 15, 14)))
    with pytest.raises(ValueError, match="larger than the 15-pixel stamp"):
        stampede.fit_stamps(s, psf=np.ones((17, 17)))
    with pytest.raises(ValueError, match="larger than the 15-pixel stamp"):
        stampede.Fitter(stamp_size=15, psf=np.ones((16, 16)))
    with pytest.raises(ValueError, match="psf holds 2 PSFs for 3 stamps"):
        stampede.fit_stamps(s, psf=np.ones((2, 5, 5)))
    with pytest.raises(ValueError, match="psf_oversampling = 0"):
        stampede.fit_stamps(s, psf=np.ones((5, 5)), psf_oversampling=0)
    with pytest.raises(ValueError, match="threads = -1"):
        stampede.fit_stamps(s, threads=-1)
    with pytest.raises(stampede.ConfigError, match="option 'stamp_size' = 39 but the stamps are 15 pixels"):
        stampede.fit_stamps(s, options={"stamp_size": 39})


def test_a_psf_that_cannot_be_normalised():
    s = np.ones((2, 15, 15))
    with pytest.raises(stampede.Error, match="PSF"):
        stampede.fit_stamps(s, psf=np.zeros((5, 5)))  # one PSF for all: the call fails
    bad = np.ones((2, 5, 5))
    bad[1] = 0.0
    rows = stampede.fit_stamps(s, psf=bad)  # one per stamp: that row is flagged
    assert rows["flags"][1] & (1 << 17) and not rows["flags"][0] & (1 << 17)


def test_errors_from_files_are_stampede_errors(tmp_path):
    with pytest.raises(stampede.FitsError, match="missing.fits") as e:
        stampede.read_image(str(tmp_path / "missing.fits"))
    assert isinstance(e.value, stampede.Error)
    junk = tmp_path / "junk.fits"
    junk.write_bytes(b"SIMPLE  = nonsense" + b"\0" * 100)
    with pytest.raises(stampede.Error, match="junk.fits"):
        stampede.run_fit(str(junk), output=str(tmp_path / "out.fits"))
    assert not (tmp_path / "out.fits").exists()


# Issue 31: np.longdouble arrays once took the interpreter down; first_id near 2**63 wrapped ids.
def test_longdouble_stamps_are_fitted_as_float64(stamps):
    rows = stampede.fit_stamps(stamps.astype(np.longdouble), options=OPTS)
    ref = stampede.fit_stamps(stamps, options=OPTS)
    assert np.array_equal(rows["e1"], ref["e1"])
    one = stampede.fit_stamp(stamps[0].astype(np.longdouble), options=OPTS)
    assert one["e1"] == ref["e1"][0]


def test_ids_that_would_pass_int64_are_refused(stamps):
    with pytest.raises(ValueError, match="first_id"):
        stampede.fit_stamps(stamps, first_id=2**63 - 3, options=OPTS)
    rows = stampede.fit_stamps(stamps, first_id=2**63 - 4, options=OPTS)
    assert rows["id"][-1] == 2**63 - 1


# Issue 31: one threads rule for every front end (0 = all cores, else 1..4096), refused before any
# work; a stamp size out of range is the option's error, not a MemoryError.
@pytest.mark.parametrize("threads", [-1, 5000, 10**6])
def test_threads_outside_the_rule_are_refused_up_front(stamps, tmp_path, threads):
    with pytest.raises(ValueError, match=f"threads = {threads}: must be 0 \\(all cores\\) or 1..4096"):
        stampede.fit_stamps(stamps, threads=threads, options=OPTS)
    with pytest.raises(ValueError, match=f"threads = {threads}: must be 0"):
        stampede.run_fit(os.path.join(MINI, "nf", "set_0.fits"), str(tmp_path / "x.fits"), threads=threads)
    assert not (tmp_path / "x.fits").exists()


def test_a_huge_stamp_size_is_a_range_error():
    with pytest.raises(ValueError, match="stamp_size"):
        stampede.Fitter(stamp_size=10**6)


def test_argument_errors_name_the_argument_and_never_print_the_array(stamps):
    for call, error, text in [
        (lambda: stampede.fit_stamps(stamps, thread=2), TypeError,
         r"fit_stamps\(\) got an unexpected keyword argument 'thread' \(it takes stamps, weights, psf, "),
        (lambda: stampede.fit_stamps(stamps, None, None, 1, True, None, 0, 0, 0, 9), TypeError,
         r"fit_stamps\(\) takes at most 9 positional arguments \(10 given\)"),
        (lambda: stampede.fit_stamps(stamps, grid_nx="2"), TypeError, r"fit_stamps\(\): grid_nx must be an int"),
        (lambda: stampede.fit_stamps(stamps, first_id=1.5), TypeError, r"first_id must be an int, not float 1.5"),
        (lambda: stampede.fit_stamps(stamps, psf_pixel_integrated=1), TypeError, "must be True or False, not int 1"),
        (lambda: stampede.fit_stamps(), TypeError, r"fit_stamps\(\) missing required argument 'stamps'"),
        (lambda: stampede.Fitter(stamp_size="39"), TypeError, r"Fitter\(\): stamp_size must be an int, not str"),
        (lambda: stampede.Fitter().fit(stamps[0], weigth=None), TypeError, "unexpected keyword argument 'weigth'"),
        (lambda: stampede.fit_stamp(stamps[0], options={"psf_fwhm": stamps[0]}), TypeError,
         r"option 'psf_fwhm' must be a number, bool or str, not numpy.ndarray float64 \(39, 39\)"),
        (lambda: stampede.simulate_great08(grid=2.5), TypeError, r"simulate_great08\(\): grid must be an int"),
        (lambda: stampede.simulate_great08(0, 2), TypeError, "takes at most 1 positional argument"),
        # The simulator's rules name the keyword given, not the command line's flag (--size).
        (lambda: stampede.simulate_great08(grid=2, size_ratio=0.9), ValueError, r"^size_ratio 0.9: Rgp/Rp must be in"),
        (lambda: stampede.read_results(3), TypeError, r"read_results\(\): path must be a str or a path"),
        (lambda: stampede.merge_shards("a.fits", "o.fits"), TypeError, "shards must be a list of paths, not str"),
        (lambda: stampede.shear_metrics([dict(g1_true=0, g2_true=0, g1="x", g2=0, err1=1, err2=1)] * 2), TypeError,
         r"shear_metrics\(\): sets\[0\]: g1 must be a number, not str 'x'"),
        (lambda: stampede.Options()[3], TypeError, "option names are strings, not int 3"),
    ]:
        with pytest.raises(error, match=text) as raised:
            call()
        assert len(str(raised.value)) < 400 and "array(" not in str(raised.value), str(raised.value)


def test_the_psf_or_the_noise_given_two_ways_is_refused(stamps):
    psf = stampede.simulate_great08(grid=1)["psf_image"]
    w = np.ones_like(stamps)
    with pytest.raises(stampede.ConfigError, match=r"psf \(an image\) and option 'psf_input' = airy both give the PSF"):
        stampede.fit_stamps(stamps, psf=psf, options={"psf_input": "airy"})
    with pytest.raises(stampede.ConfigError, match=r"Fitter\(\): psf \(an image\) and option 'psf_input'"):
        stampede.Fitter({"psf_input": "moffat"}, psf=psf)
    with pytest.raises(stampede.ConfigError, match="option 'noise_sigma' = 1 and fit_stamps\\(\\): weights both give"):
        stampede.fit_stamps(stamps, weights=w, options={"noise_sigma": 1})
    with pytest.raises(stampede.ConfigError, match="option 'noise_sigma' = 2 and Fitter.fit\\(\\): weight both"):
        stampede.Fitter({"noise_sigma": 2}).fit(stamps[0], weight=w[0])
    with pytest.raises(stampede.ConfigError, match="psf_image = 'p.fits' with psf_input = airy: the image would not"):
        stampede.Options(psf_input="airy", psf_image="p.fits")
    # One way each is fine: the image PSF with the default psf_input, weights with noise_sigma 0.
    assert len(stampede.fit_stamps(stamps, psf=psf, weights=w, options=OPTS)) == 4


def test_selections_usable_flags_and_pairs_are_whole_numbers_in_range():
    """metacal_set_shear(selected=...) and set_shear(usable=..., pair=...) refuse what a cast would
    silently change (0.9 -> 0, 256 -> 0, -1 -> 255, NaN -> anything) and name the value; in-range
    whole numbers are taken as they are."""
    n = 4
    e = np.array([0.1, -0.1, 0.2, -0.2])
    one, zero = np.ones(n), np.zeros(n)
    pair = np.array([0, 0, 1, 1])

    def metacal(selected, pair=pair):
        return stampede.metacal_set_shear(e, e, one, zero, zero, one, selected, pair, 0.0, 0.0, bootstrap=10)

    for bad, text in [(np.array([0x1f, 0x1f, 0.9, 0x1f]), r"selected\[2\] = 0.9: not a whole number"),
                      (np.array([0x1f, 256, 0x1f, 0x1f]), r"selected\[1\] = 256: must be 0..31"),
                      (np.array([-1, 0x1f, 0x1f, 0x1f]), r"selected\[0\] = -1: must be 0..31"),
                      (np.array([0x1f, 0x1f, 0x1f, np.nan]), r"selected\[3\] = nan: not a whole number")]:
        with pytest.raises(ValueError, match=text):
            metacal(bad)
    with pytest.raises(TypeError, match="selected must hold integers 0..31, not booleans"):
        metacal(np.ones(n, dtype=bool))
    with pytest.raises(ValueError, match=r"pair\[1\] = nan: not a whole number"):
        metacal(np.full(n, 0x1f), pair=np.array([0.0, np.nan, 1.0, 1.0]))
    whole = metacal(np.array([31.0, 31.0, 31.0, 31.0]))  # floats holding whole numbers are fine
    assert whole == metacal(np.full(n, 0x1f, dtype=np.uint8)) and whole["used"] == 4
    assert whole["selected_units"] == {"noshear": 2, "1p": 2, "1m": 2, "2p": 2, "2m": 2}
    # set_shear: usable 0/1 or booleans.
    for bad, text in [(np.array([1, 1, 0.5, 1]), r"usable\[2\] = 0.5: not a whole number"),
                      (np.array([1, 2, 1, 1]), r"usable\[1\] = 2: must be 0 or 1"),
                      (np.array([1, 1, 1, np.nan]), r"usable\[3\] = nan: not a whole number")]:
        with pytest.raises(ValueError, match=text):
            stampede.set_shear(e, e, bad, pair, 0.0, 0.0)
    with pytest.raises(ValueError, match=r"pair\[0\] = 0.5: not a whole number"):
        stampede.set_shear(e, e, np.ones(n, dtype=bool), np.array([0.5, 0, 1, 1]), 0.0, 0.0)
    assert stampede.set_shear(e, e, np.ones(n, dtype=bool), pair, 0.0, 0.0)["used"] == 4


def test_an_error_from_fewer_than_two_ring_pairs_is_nan_not_zero():
    """One usable ring pair: the bootstrap resamples it to itself, so it has no error to give (NaN,
    'units' says why), never 0; a line through two such sets has no error either."""
    e = np.array([0.1, -0.05, 0.3, -0.3])
    pair = np.array([0, 0, 1, 1])
    one_pair = np.array([1, 1, 0, 0])
    s = stampede.set_shear(e, e, one_pair, pair, 0.01, -0.01)
    assert s["units"] == 1 and s["used"] == 2
    assert math.isnan(s["err1"]) and math.isnan(s["err2"])
    both = stampede.set_shear(e, e, np.ones(4, dtype=int), pair, 0.01, 0.0)
    assert both["units"] == 2 and both["err1"] > 0
    one, zero = np.ones(4), np.zeros(4)
    sel = np.where(one_pair == 1, 0x1f, 0)
    mc = stampede.metacal_set_shear(e, e, one, zero, zero, one, sel, pair, 0.01, 0.0)
    assert mc["units"] == 1 and math.isnan(mc["err1"]) and math.isnan(mc["err2"])
    sets = [dict(s), dict(stampede.set_shear(e + 0.02, e, one_pair, pair, 0.03, -0.03))]
    m = stampede.shear_metrics(sets)
    assert math.isfinite(m["m1"]) and math.isnan(m["m1_err"]) and math.isnan(m["c1_err"])
