"""stampede.read_table, fits_hdus, fits_header and read_image(hdu=): a `stampede fit` table read in
row chunks equals read_results' columns, and a bad HDU, column or range is an error naming it."""

import numpy as np
import pytest

import stampede
from conftest import run_cli


@pytest.fixture(scope="module")
def fit(tmp_path_factory):
    """A small simulated set and its `stampede fit` table."""
    d = tmp_path_factory.mktemp("read_table")
    run_cli("sim", "great08", "--out", str(d / "sim"), "--sets", "1", "--grid", "3", "--stamp", "32", "--snr", "20",
            "--galaxy", "disc", "--threads", "2")
    out = d / "fit.fits"
    run_cli("fit", str(d / "sim" / "set_0.fits"), "-o", str(out), "--threads", "2", "--quiet")
    return {"table": out, "image": d / "sim" / "set_0.fits"}


def test_chunks_equal_read_results(fit):
    rows = stampede.read_results(fit["table"])
    names = list(rows.dtype.names)
    n = rows.size
    assert n == 9
    chunks = [stampede.read_table(fit["table"], "RESULTS", names, first_row=start, count=min(4, n - start))
              for start in range(0, n, 4)]
    assert [c["id"].size for c in chunks] == [4, 4, 1]
    for name in names:
        got = np.concatenate([c[name] for c in chunks])
        want = rows[name]
        if want.dtype.kind in "iu":
            assert got.dtype == np.int64, name
            assert np.array_equal(got, want.astype(np.int64)), name
        else:
            assert got.dtype == np.float64, name
            assert got.tobytes() == np.ascontiguousarray(want, dtype=np.float64).tobytes(), name  # bitwise, NaN too
    # By index as well as by name, and to the end without count.
    index = next(h["index"] for h in stampede.fits_hdus(fit["table"]) if h["name"] == "RESULTS")
    tail = stampede.read_table(fit["table"], index, ["e1"], first_row=7)
    assert tail["e1"].tobytes() == rows["e1"][7:].tobytes()
    assert stampede.read_table(fit["table"], "RESULTS", ["e1"], first_row=n)["e1"].size == 0


def test_hdus_and_header(fit):
    hdus = stampede.fits_hdus(fit["table"])
    assert hdus[0]["index"] == 0 and hdus[0]["kind"] == "empty" and hdus[0]["rows"] is None
    results = [h for h in hdus if h["name"] == "RESULTS"]
    assert len(results) == 1 and results[0]["kind"] == "table" and results[0]["rows"] == 9
    assert set(stampede.read_results(fit["table"]).dtype.names) <= set(results[0]["columns"])
    cards = stampede.fits_header(fit["table"], "RESULTS")
    assert cards[0][:2] == ("XTENSION", "BINTABLE")
    values = {k: v for k, v, _ in cards}
    assert values["EXTNAME"] == "RESULTS" and values["NAXIS2"] == 9 and isinstance(values["NAXIS2"], int)
    assert isinstance(values["RUNFP"], str) and values["RUNFP"]
    assert any(k == "COMMENT" and v.startswith("flags bit ") for k, v, _ in cards)
    assert "CONTINUE" not in values  # long strings are joined, not listed card by card
    image = stampede.fits_hdus(fit["image"])
    assert image[0]["kind"] == "image" and image[0]["columns"] == []
    assert dict((k, v) for k, v, _ in stampede.fits_header(fit["image"]))["NAXIS"] == 2


def test_read_image_by_hdu(fit):
    pixels = stampede.read_image(fit["image"])
    assert pixels.shape == (96, 96)
    assert stampede.read_image(fit["image"], hdu=0).tobytes() == pixels.tobytes()
    with pytest.raises(stampede.FitsError, match=r"fit\.fits\[HDU 1 'RESULTS'\]: not an image"):
        stampede.read_image(fit["table"], hdu="RESULTS")


def test_bad_column_hdu_or_range_is_a_clear_error(fit):
    path = str(fit["table"])
    with pytest.raises(stampede.FitsError) as e:
        stampede.read_table(path, "RESULTS", ["e1", "e3"])
    assert path in str(e.value) and "[HDU 1 'RESULTS']: no column 'e3'" in str(e.value)
    with pytest.raises(stampede.FitsError, match="no HDU with EXTNAME 'TRUTH'") as e:
        stampede.read_table(path, "TRUTH", ["e1"])
    assert path in str(e.value)
    with pytest.raises(stampede.FitsError, match="cannot move to HDU 7") as e:
        stampede.read_table(path, 7, ["e1"])
    assert path in str(e.value)
    with pytest.raises(stampede.FitsError, match=r"\[HDU 0\]: not a table"):
        stampede.read_table(path, 0, ["e1"])
    with pytest.raises(stampede.FitsError, match="cannot open FITS file") as e:
        stampede.read_table(path + ".missing", "RESULTS", ["e1"])
    with pytest.raises(ValueError, match=r"read_table\(\): rows 5\.\.14 are beyond the 9 rows of .*fit\.fits\[HDU 1"):
        stampede.read_table(path, "RESULTS", ["e1"], first_row=5, count=10)
    with pytest.raises(ValueError, match="first_row = -1"):
        stampede.read_table(path, "RESULTS", ["e1"], first_row=-1)
    with pytest.raises(TypeError, match=r"read_table\(\): columns must be a list of str"):
        stampede.read_table(path, "RESULTS", "e1")
    with pytest.raises(TypeError, match=r"read_table\(\): hdu must be an HDU index .* or an EXTNAME"):
        stampede.read_table(path, 1.0, ["e1"])
    with pytest.raises(TypeError, match=r"fits_header\(\) missing required argument 'path'"):
        stampede.fits_header()
