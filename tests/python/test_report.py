"""`python3 -m stampede.report`: the page and its figures from a small simulation with truth, its
m and c against `stampede metrics`' output, and the refusals of bad inputs."""

import glob
import html
import os
import re
import subprocess
import sys

import pytest

from conftest import run_cli

matplotlib_image = pytest.importorskip("matplotlib.image", reason="python3-matplotlib is not installed")

SETS = 3
FIGURES = {"status.png", "distributions.png", "psf_leakage.png", "e_vs_truth.png", "bias_bins.png", "residuals.png"}


def report(*args):
    return subprocess.run([sys.executable, "-m", "stampede.report", *map(str, args)], capture_output=True, text=True)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """Three small simulated sets fitted by `stampede fit` (set 0 saving some images) and the
    `stampede metrics` output for them."""
    d = tmp_path_factory.mktemp("report")
    sim = d / "sim"
    run_cli("sim", "great08", "--out", str(sim), "--sets", str(SETS), "--grid", "8", "--stamp", "32", "--snr", "20",
            "--galaxy", "disc", "--threads", "2")
    fits = []
    for k in range(SETS):
        out = d / f"fit_{k}.fits"
        extra = ["--set", "save_images=0,1,2,3,4,5,6,7,8,9"] if k == 0 else []
        run_cli("fit", str(sim / f"set_{k}.fits"), "-o", str(out), "--threads", "2", "--quiet", *extra)
        fits.append(out)
    metrics_args = [a for k in range(SETS) for a in ("--fit", str(fits[k]), "--truth", str(sim / f"truth_{k}.fits"))]
    metrics = run_cli("metrics", *metrics_args).stdout
    return {"dir": d, "sim": sim, "fits": fits, "metrics": metrics}


def test_report_has_every_figure_and_the_metrics_numbers(run):
    out = run["dir"] / "page"
    r = report(*run["fits"], "--truth", run["sim"], "--images", run["dir"] / "fit_0.images.fits", "-o", out)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == str(out / "report.html")
    page = (out / "report.html").read_text(encoding="utf-8")
    shown = set(re.findall(r'<img src="([^"]+)"', page))
    assert shown == FIGURES and set(os.listdir(out)) == FIGURES | {"report.html"}
    for name in shown:  # every figure decodes as an image of a sensible size
        pixels = matplotlib_image.imread(str(out / name))
        assert pixels.ndim == 3 and pixels.shape[0] > 150 and pixels.shape[1] > 300, name
        assert pixels.std() > 0, name  # not blank
    assert "http://" not in page and "https://" not in page and "<script" not in page  # self-contained
    # The numbers `stampede metrics` prints, line for line: per set, m and c, the PSF frame, Q.
    text = html.unescape(page)
    lines = [l for l in run["metrics"].splitlines() if l.strip()]
    assert sum(l.startswith(("m1 = ", "m2 = ")) for l in lines) == 2 and len(lines) == SETS + 5
    for line in lines:
        assert line in text, line
    # The residual mosaic shows the saved objects with the largest chi2 first.
    table = page[page.index("worst χ²"):]
    chi2 = [float(x) for x in re.findall(r"<tr><td class=\"text\">\d+</td><td class=\"\">([^<]+)</td>", table)]
    assert len(chi2) == 8 and chi2 == sorted(chi2, reverse=True)


def test_an_existing_report_is_replaced_only_with_overwrite(run):
    out = run["dir"] / "again"
    assert report(run["fits"][0], "-o", out).returncode == 0
    r = report(run["fits"][0], "-o", out)
    assert r.returncode == 1 and "--overwrite" in r.stderr and str(out) in r.stderr
    r = report(run["fits"][1], "-o", out, "--overwrite")
    assert r.returncode == 0, r.stderr
    assert "fit_1.fits" in (out / "report.html").read_text(encoding="utf-8")


def empty_table(source, path):
    """`source` with NAXIS2 = 0 and no rows: a valid FITS result table without objects."""
    data = bytearray(source.read_bytes())
    at = data.index(b"NAXIS2  =", data.index(b"XTENSION"))
    data[at:at + 30] = b"NAXIS2  = %20d" % 0
    end = data.index(b"END" + b" " * 77, at)
    header_end = (end // 2880 + 1) * 2880
    path.write_bytes(bytes(data[:header_end]))
    return path


def refused(run, name, args, *expected):
    """The report is refused with an error naming the expected files and no report is left."""
    out = run["dir"] / f"refused_{name}"
    r = report(*args, "-o", out)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "Traceback" not in r.stderr and r.stderr.startswith("stampede.report: ")
    for text in expected:
        assert str(text) in r.stderr, (text, r.stderr)
    assert not out.exists()
    assert not glob.glob(str(run["dir"] / ".report-*"))
    return r.stderr


def test_bad_inputs_are_refused_by_name_and_write_nothing(run, tmp_path):
    truth0 = run["sim"] / "truth_0.fits"
    # Not a result table: a truth table, and a file that is not FITS.
    refused(run, "truth_as_table", [truth0], truth0, "not a `stampede fit` result table", "no RESULTS HDU")
    text = tmp_path / "notes.fits"
    text.write_text("not a FITS file\n" * 200)
    refused(run, "text", [text], text, "not a FITS file")
    # The truth of another set of the same run, and the truth of another run altogether.
    err = refused(run, "other_set", [run["fits"][0], "--truth", run["sim"] / "truth_1.fits"], run["fits"][0],
                  run["sim"] / "truth_1.fits")
    assert "SETIDX=0" in err and "SETIDX=1" in err
    other = tmp_path / "other"
    run_cli("sim", "great08", "--out", str(other), "--sets", "1", "--grid", "2", "--stamp", "32", "--seed", "99",
            "--galaxy", "disc")
    err = refused(run, "other_run", [*run["fits"], "--truth", other], run["fits"][0], other)
    assert "no truth file" in err
    # An empty table.
    empty = empty_table(run["fits"][1], tmp_path / "empty.fits")
    refused(run, "empty", [run["fits"][0], empty], empty, "no rows")
    # save_images output of no table given.
    refused(run, "images", [run["fits"][1], "--images", run["dir"] / "fit_0.images.fits"], "fit_0.images.fits",
            "not the save_images file of any table")


def test_metacal_tables_give_the_metacal_numbers_of_metrics(run):
    """With metacal columns the page adds R11/R22 and the calibrated per-set shears, m and c, equal
    to `stampede metrics --metacal`'s printed lines (no cuts)."""
    fits = []
    for k in range(2):
        out = run["dir"] / f"metacal_{k}.fits"
        run_cli("fit", str(run["sim"] / f"set_{k}.fits"), "-o", str(out), "--set", "metacal=true", "--threads", "2",
                "--quiet")
        fits.append(out)
    args = [a for k in range(2) for a in ("--fit", str(fits[k]), "--truth", str(run["sim"] / f"truth_{k}.fits"))]
    printed = run_cli("metrics", "--metacal", *args).stdout
    out = run["dir"] / "metacal_page"
    r = report(*fits, "--truth", run["sim"], "-o", out)
    assert r.returncode == 0, r.stderr
    text = html.unescape((out / "report.html").read_text(encoding="utf-8"))
    assert "metacal_R.png" in text and matplotlib_image.imread(str(out / "metacal_R.png")).shape[0] > 150
    section = text[text.index("Metacalibration"):]
    lines = [l for l in printed.splitlines() if l.strip() and "<R> =" not in l]
    assert len(lines) == 2 + 5
    for line in lines:
        assert line in section, line


def snapshot(directory):
    """{name: bytes} of the files in `directory` (not recursive)."""
    return {name: (directory / name).read_bytes() for name in os.listdir(directory) if (directory / name).is_file()}


def test_overwrite_replaces_only_the_reports_own_files(run, tmp_path):
    """A directory holding anything besides a report's files (the input table, notes) is refused by
    name with --overwrite too, and left exactly as it was; so is `-o .` there. A directory holding
    only an earlier report is updated in place: its figures and page replaced, a figure the new
    report lacks removed, nothing left behind in it or beside it."""
    mixed = tmp_path / "mixed"
    mixed.mkdir()
    assert report(run["fits"][0], "-o", mixed).returncode == 0
    table = mixed / "fit_0.fits"
    table.write_bytes(run["fits"][0].read_bytes())
    (mixed / "notes.txt").write_text("mine\n")
    before = snapshot(mixed)
    r = report(table, "-o", mixed, "--overwrite")
    assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr
    assert "fit_0.fits" in r.stderr and "notes.txt" in r.stderr and "not a report's" in r.stderr
    assert snapshot(mixed) == before
    # `-o .` inside it: refused the same way, nothing left in the parent.
    r = subprocess.run([sys.executable, "-m", "stampede.report", "fit_0.fits", "-o", ".", "--overwrite"],
                       capture_output=True, text=True, cwd=mixed)
    assert r.returncode == 1 and "Traceback" not in r.stderr and "notes.txt" in r.stderr, r.stderr
    assert snapshot(mixed) == before
    assert sorted(os.listdir(tmp_path)) == ["mixed"]
    # A directory holding only a report (with a figure the next report does not draw): replaced in
    # place, through `-o .`.
    only = tmp_path / "only"
    assert report(run["fits"][0], "-o", only).returncode == 0
    (only / "metacal_R.png").write_bytes((only / "status.png").read_bytes())
    r = subprocess.run([sys.executable, "-m", "stampede.report", str(run["fits"][1]), "-o", ".", "--overwrite"],
                       capture_output=True, text=True, cwd=only)
    assert r.returncode == 0, r.stderr
    assert "fit_1.fits" in (only / "report.html").read_text(encoding="utf-8")
    assert set(os.listdir(only)) == {"report.html", "status.png", "distributions.png", "psf_leakage.png"}
    assert sorted(os.listdir(tmp_path)) == ["mixed", "only"]


def survey_table(tmp_path):
    """A small survey (MEDS) fit: 4 simulated objects."""
    sim = tmp_path / "meds"
    run_cli("sim", "meds", "--out", str(sim), "--objects", "4", "--epochs", "2", "--snr", "30")
    out = tmp_path / "survey.fits"
    run_cli("fit", "--meds", str(sim / "meds.fits"), "-o", str(out), "--threads", "2", "--quiet")
    return out


def test_a_table_given_twice_or_grid_with_survey_tables_is_refused(run, tmp_path):
    # The same file twice: by the same path, by another spelling of it, and through a hard link.
    refused(run, "twice", [run["fits"][0], run["fits"][1], run["fits"][0]], run["fits"][0], "given twice")
    other_spelling = f"{run['dir']}/./{run['fits'][0].name}"
    refused(run, "spelling", [run["fits"][0], other_spelling], "given twice")
    link = tmp_path / "link.fits"
    os.link(run["fits"][1], link)
    refused(run, "hard_link", [run["fits"][1], link], link, "given twice")
    # A grid table with a survey table: pixels and arcsec, chi2/dof and chi2.
    survey = survey_table(tmp_path)
    refused(run, "grid_survey", [run["fits"][0], survey], survey, run["fits"][0], "survey (MEDS)", "separately")
    refused(run, "survey_grid", [survey, run["fits"][0]], survey, run["fits"][0], "survey (MEDS)")


def test_a_survey_table_with_another_simulations_truth_is_refused(run, tmp_path):
    """A `sim meds` tile and its truth carry the simulation's SIMID, which the fit records as
    INSETID: the truth of another simulation (same ids, same row count) is refused by name, as by
    `stampede metrics`; the tile's own truth is accepted."""
    survey = survey_table(tmp_path)
    other = tmp_path / "other"
    run_cli("sim", "meds", "--out", str(other), "--objects", "4", "--epochs", "2", "--snr", "30", "--seed", "12")
    err = refused(run, "other_simulation", [survey, "--truth", other / "truth.fits"], survey, other / "truth.fits",
                  "(INSETID)")
    assert err.count("SIMID=") == 2
    own = tmp_path / "own"
    r = report(survey, "--truth", tmp_path / "meds" / "truth.fits", "-o", own)
    assert r.returncode == 0, r.stderr


def with_column(source, path, name, value):
    """A copy of the result table `source` with every row's real column `name` set to `value`."""
    import struct
    data = bytearray(source.read_bytes())
    start = data.index(b"XTENSION")
    cards = {}
    at = start
    while True:
        card = data[at:at + 80].decode()
        at += 80
        if card.startswith("END "):
            break
        if card[8:10] == "= ":
            cards[card[:8].strip()] = card[10:].split("/")[0].strip().strip("'").strip()
    data_start = (at + 2879) // 2880 * 2880
    widths = {"D": 8, "K": 8, "J": 4, "V": 4, "E": 4, "I": 2}
    offset, column = 0, None
    for k in range(1, int(cards["TFIELDS"]) + 1):
        if cards[f"TTYPE{k}"] == name:
            assert cards[f"TFORM{k}"] in ("1D", "1E")
            column, form = offset, ">d" if cards[f"TFORM{k}"] == "1D" else ">f"
        offset += widths[cards[f"TFORM{k}"][-1]]
    assert column is not None and offset == int(cards["NAXIS1"])
    size = struct.calcsize(form)
    for row in range(int(cards["NAXIS2"])):
        data[data_start + row * offset + column:data_start + row * offset + column + size] = struct.pack(form, value)
    path.write_bytes(bytes(data))
    return path


def test_huge_fluxes_give_a_report_not_a_traceback(run, tmp_path):
    """Fluxes near 1e162 (finite; their squares are not): the report is written and says them."""
    table = run["fits"][2]
    for name in ("flux", "bulge_flux"):
        table = with_column(table, tmp_path / f"huge_{name}.fits", name, 1.5e162)
    out = tmp_path / "huge"
    r = report(table, "-o", out)
    assert r.returncode == 0 and "Traceback" not in r.stderr and "Warning" not in r.stderr, r.stderr
    text = html.unescape((out / "report.html").read_text(encoding="utf-8"))
    assert "1.5e+162" in text


def edited(source, path, *replacements):
    """A copy of `source` with header bytes replaced (each old and new of one length, so the file's
    layout is kept)."""
    data = source.read_bytes()
    for old, new in replacements:
        assert len(old) == len(new) and data.count(old) == 1, old
        data = data.replace(old, new)
    path.write_bytes(data)
    return path


def as_reals(source, path, name):
    """A copy of `source` whose integer column `name` is declared real of its width ('1J' -> '1E',
    '1K' -> '1D')."""
    return declared(source, path, name, {b"J": b"E", b"K": b"D"})


def declared(source, path, name, forms):
    """A copy of `source` whose column `name` is declared of another type of the same width (forms:
    old TFORM letter -> new), its bytes unchanged."""
    data = source.read_bytes()
    at, number = data.index(b"XTENSION"), None
    while not data[at:at + 80].startswith(b"END "):
        c = data[at:at + 80].decode()
        if c.startswith("TTYPE") and c[10:].split("/")[0].strip().strip("'").strip() == name:
            number = c[5:8].strip()
        at += 80
    form = data.index(f"TFORM{number}".ljust(8).encode() + b"= '1")
    path.write_bytes(data[:form + 12] + forms[data[form + 12:form + 13]] + data[form + 13:])
    return path


def card(key, value):
    return f"{key:<8s}= {value:>20s}".encode().ljust(80)


def test_damaged_tables_are_refused_by_name_or_reported(run, tmp_path):
    """Found by fuzz/fuzz_metrics_report.py: damaged or unusual tables ended the report in a
    traceback or in warnings; each is now a report or a refusal naming file, column and row."""
    table = run["fits"][1]
    # No disc_flux column (not a required one): KeyError before; now reported without it.
    renamed = edited(table, tmp_path / "no_disc_flux.fits", (b"'disc_flux'", b"'disc_flxx'"))
    r = report(renamed, "-o", tmp_path / "no_disc_flux")
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
    # Every e1 at 1e308: an OverflowError (and overflow warnings) drawing the histograms before.
    huge = with_column(table, tmp_path / "huge_e.fits", "e1", 1e308)
    r = report(huge, "--truth", run["sim"], "-o", tmp_path / "huge_e")
    assert r.returncode == 0 and "Traceback" not in r.stderr and "Warning" not in r.stderr, r.stderr
    # A status column of reals holding NaN: a TypeError on the flag bits before; now named.
    nan_status = with_column(as_reals(table, tmp_path / "status_reals.fits", "status"), tmp_path / "status_nan.fits",
                             "status", float("nan"))
    refused(run, "status_nan", [nan_status], nan_status, "column 'status' row 0 = nan is not an integer in [0, ")
    # An e2 column declared 64-bit integer (found by the fuzzer, case 69/41): a TypeError in set_shear.
    integer_e = declared(table, tmp_path / "integer_e2.fits", "e2", {b"D": b"K"})
    r = report(integer_e, "--truth", run["sim"], "-o", tmp_path / "integer_e2")
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
    # A truth whose shear is text: a ValueError traceback before.
    truth = run["sim"] / "truth_1.fits"
    text_truth = truth.read_bytes()
    at = text_truth.index(b"SHEAR1  =")
    bad = tmp_path / "text_shear_truth.fits"
    bad.write_bytes(text_truth[:at] + card("SHEAR1", "'x'").ljust(80) + text_truth[at + 80:])
    refused(run, "text_shear", [table, "--truth", bad], bad, "SHEAR1, SHEAR2 = 'x'", "is not a shear")


def test_two_fits_of_one_set_have_no_line(run, tmp_path):
    """A plain and a metacal fit of one set, with the simulation's truth: one true shear, so no m and
    c (`fit_linear_bias` raised through the report before); said as `stampede metrics` says it."""
    mcal = tmp_path / "metacal_0.fits"
    run_cli("fit", str(run["sim"] / "set_0.fits"), "-o", str(mcal), "--set", "metacal=true", "--threads", "2", "--quiet")
    out = tmp_path / "page"
    r = report(mcal, run["fits"][0], "--truth", run["sim"], "-o", out)
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
    text = html.unescape((out / "report.html").read_text(encoding="utf-8"))
    assert "m, c: need at least two sets with different shears" in text
    printed = run_cli("metrics", "--fit", str(mcal), "--truth", str(run["sim"] / "truth_0.fits"), "--fit",
                      str(run["fits"][0]), "--truth", str(run["sim"] / "truth_0.fits")).stdout
    assert "m, c: need at least two sets with different shears" in printed
