"""`python3 -m stampede.report` on `stampede metadetect` tables: the metadetection page from a small
shear pair of simulated cells, its numbers against `stampede metrics --metadetect`'s output on the
same tables, and the refusals of bad inputs."""

import html
import json
import math
import os
import re
import subprocess
import sys

import pytest

import stampede
from conftest import run_cli

matplotlib_image = pytest.importorskip("matplotlib.image", reason="python3-matplotlib is not installed")

FIGURES = {"metadetect_cuts.png", "metadetect_response.png"}
CELLS = 3


def report(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "stampede.report", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd)


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    """Three S/N 20 cells and their shear pair (g1 = +-0.02) through `stampede metadetect`, and
    `stampede metrics --metadetect` on them (printed and JSON), run in the tables' directory so
    that the paths the page prints are the command's."""
    d = tmp_path_factory.mktemp("mdet")
    run_cli("sim", "cells", "--out", str(d / "sim"), "--cells", str(CELLS), "--pair", "--snr", "20", "--threads", "2")
    for sign, sub in (("plus", ""), ("minus", "minus/")):
        run_cli("metadetect", *[str(d / "sim" / f"{sub}cell_{k:04d}.fits") for k in range(CELLS)],
                "-o", str(d / f"{sign}.fits"), "--threads", "2", "--quiet")
    cli = os.environ.get("STAMPEDE_CLI", "stampede")

    def metrics(*args):
        r = subprocess.run([cli, "metrics", "--metadetect", *args], capture_output=True, text=True, cwd=d)
        assert r.returncode == 0, r.stderr
        return r.stdout

    printed = metrics("plus.fits", "--minus", "minus.fits", "--json", "pair.json")
    printed_plus = metrics("plus.fits", "--json", "plus.json")
    return {"dir": d, "plus": d / "plus.fits", "minus": d / "minus.fits", "printed": printed,
            "printed_plus": printed_plus, "json": json.loads((d / "pair.json").read_text()),
            "json_plus": json.loads((d / "plus.json").read_text())}


def page_text(out):
    return html.unescape((out / "report.html").read_text(encoding="utf-8"))


def as_json(v):
    """A number as the command writes it into its JSON (printf %.6e; NaN as null)."""
    return float(f"{v:.6e}") if math.isfinite(v) else None


def test_the_page_shows_the_metrics_of_the_command(pair):
    d = pair["dir"]
    r = report("plus.fits", "minus.fits", "-o", "page", cwd=d)
    assert r.returncode == 0, r.stderr
    out = d / "page"
    assert r.stdout.strip() == os.path.join("page", "report.html")
    page = (out / "report.html").read_text(encoding="utf-8")
    shown = set(re.findall(r'<img src="([^"]+)"', page))
    assert shown == FIGURES and set(os.listdir(out)) == FIGURES | {"report.html"}
    for name in shown:  # every figure decodes as a non-blank image of a sensible size
        pixels = matplotlib_image.imread(str(out / name))
        assert pixels.ndim == 3 and pixels.shape[0] > 300 and pixels.shape[1] > 600 and pixels.std() > 0, name
    assert "http://" not in page and "https://" not in page and "<script" not in page
    # Every line `stampede metrics --metadetect plus.fits --minus minus.fits` printed, as printed.
    text = page_text(out)
    lines = [l for l in pair["printed"].splitlines() if l.strip()]
    assert len(lines) == 5 and lines[3].startswith("shear pair with minus.fits, g = (0.02, 0), 3 pairs")
    for line in lines:
        assert line in text, line
    for kind in ("noshear", "1p", "1m", "2p", "2m"):
        assert f"plus.fits{kind}" in re.sub(r"<[^>]+>", "", page)  # a counts row per shear type and table
    # One table alone: the lines of `stampede metrics --metadetect plus.fits`, no pair.
    r = report("plus.fits", "-o", "page_plus", cwd=d)
    assert r.returncode == 0, r.stderr
    text = page_text(d / "page_plus")
    for line in (l for l in pair["printed_plus"].splitlines() if l.strip()):
        assert line in text, line
    assert "shear pair with" not in text and "pairs of cells" not in text


def test_the_numbers_equal_the_commands_json(pair):
    """The page's numbers (stampede.report.metadetect.compute, what write_page draws from) equal
    the command's JSON for the same tables, and its counts equal the rows counted directly."""
    from stampede.report import metadetect as md
    inputs = md.MetadetectInputs([str(pair["plus"]), str(pair["minus"])])
    n = md.compute(inputs, chunk_rows=1 << 18)
    single, both = n["single"][0], n["pair"]
    js, jp = pair["json_plus"], pair["json"]
    for key in ("R11", "R11_err", "R22", "R22_err", "g1", "g1_err", "g2", "g2_err"):
        assert as_json(single[key]) == js[key] == jp[key], key
    for key in ("m1", "m1_err", "c2", "c2_err", "m2", "m2_err", "c1", "c1_err"):
        assert as_json(both[key]) == jp[key], key
    assert single["cells"] == jp["cells"] == CELLS and both["pairs"] == jp["pairs"] == CELLS
    assert [as_json(g) for g in both["shear"]] == jp["shear"] == [0.02, 0.0]
    assert jp["m2"] is None and math.isnan(both["m2"])  # a shear along g1: no m2
    # Counts per shear type from the rows themselves; the noshear count after the cuts is the
    # command's kept_noshear.
    for t, counts in zip(inputs.tables, n["counts"]):
        rows = stampede.read_table(t.path, "METADETECT", ["shear_type", "id", "flags", "snr", "T_ratio", "e1", "e2"])
        assert rows["shear_type"].dtype.kind == "U"
        for k, kind in enumerate(md.SHEAR_TYPES):
            of = (rows["shear_type"] == kind) & (rows["id"] >= 0)
            kept = of & (rows["flags"] == 0) & (rows["snr"] > 10) & (rows["T_ratio"] > 1.2)
            assert counts.detections[k] == of.sum() > 0 and counts.kept[k] == kept.sum(), kind
            assert counts.e_sums[k, 0] == pytest.approx(rows["e1"][kept].sum(), abs=1e-12)
        assert sum(counts.per_cell.values()) == counts.detections[0] and len(counts.per_cell) == CELLS
    assert n["counts"][0].kept[0] == single["kept_noshear"]
    # Streamed in chunks of a few rows: the same counts.
    small = md.compute(inputs, chunk_rows=37)
    for a, b in zip(n["counts"], small["counts"]):
        assert (a.detections == b.detections).all() and (a.kept == b.kept).all() and a.per_cell == b.per_cell
    # The shear given explicitly is the one the inputs' G1, G2 keys give.
    given = md.compute(md.MetadetectInputs([str(pair["plus"]), str(pair["minus"])], (0.02, 0.0)),
                       1 << 18)
    assert given["pair"]["m1"] == both["m1"]


def edited_bytes(source, path, old, new, after_header=False):
    """A copy of `source` with the first `old` (after the METADETECT header when after_header)
    replaced by `new` of the same length."""
    data = bytearray(source.read_bytes())
    start = 0
    if after_header:
        at = data.index(b"METADETECT")
        while not data[at - at % 80:at - at % 80 + 80].startswith(b"END "):
            at += 80
        start = (at // 2880 + 1) * 2880
    at = data.index(old, start)
    assert len(old) == len(new)
    data[at:at + len(old)] = new
    path.write_bytes(bytes(data))
    return path


def refused(d, name, tables, *expected, **options):
    """build_report (in this process: quicker than the command) refuses with a ReportError naming
    `expected`, and writes nothing."""
    from stampede.report import ReportError, build_report
    out = d / f"refused_{name}"
    with pytest.raises(ReportError) as e:
        build_report(tables, out, **options)
    for text in expected:
        assert str(text) in str(e.value), (text, str(e.value))
    assert not out.exists() and not list(d.glob(".report-*"))


def test_bad_metadetect_inputs_are_refused_by_name(pair, tmp_path):
    plus, minus = pair["plus"], pair["minus"]
    cell = pair["dir"] / "sim" / "cell_0000.fits"
    # By the command: exit 1, the message without a traceback, nothing written.
    r = report(plus, cell, "-o", tmp_path / "mixed")
    assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr
    assert r.stderr == f"stampede.report: {plus} is a `stampede metadetect` table but {cell} is not: report them " \
                       "separately\n"
    assert not (tmp_path / "mixed").exists()
    third = tmp_path / "third.fits"
    third.write_bytes(minus.read_bytes())
    refused(tmp_path, "three", [plus, minus, third], "3 metadetect tables", "give one table, or a shear pair")
    refused(tmp_path, "twice", [plus, plus], "given twice")
    refused(tmp_path, "truth", [plus, minus], "--truth and --images are for", truth=pair["dir"] / "sim")
    refused(tmp_path, "shear_alone", [plus], "--shear is the true shear of a metadetect shear pair", shear=(0.02, 0))
    # A column renamed: named with the file and HDU.
    no_t_ratio = edited_bytes(plus, tmp_path / "no_t_ratio.fits", b"= 'T_ratio", b"= 'T_ratix")
    refused(tmp_path, "no_t_ratio", [no_t_ratio], f"{no_t_ratio}[HDU 1 'METADETECT']: no column 'T_ratio'")
    # A shear type no run writes: named with its column and row.
    bad_type = edited_bytes(plus, tmp_path / "bad_type.fits", b"noshear", b"sheared", after_header=True)
    refused(tmp_path, "bad_type", [bad_type], bad_type, "column 'shear_type' row 0 = 'sheared' is not one of")
    # Not a pair: the minus table of other cells.
    other = tmp_path / "two_cells.fits"
    run_cli("metadetect", *[str(pair["dir"] / "sim" / "minus" / f"cell_{k:04d}.fits") for k in range(2)],
            "-o", str(other), "--threads", "2", "--quiet")
    refused(tmp_path, "not_pair", [plus, other], plus, other, "not a shear pair")
    # The table records its inputs' shear (SHEAR1, SHEAR2): the page needs no input file. A table
    # without that record (an older run's) takes it from its first input; that input gone, the
    # error says to give it; given, the page.
    moved = edited_bytes(plus, tmp_path / "moved.fits", b"cell_0000.fits", b"cell_9999.fits")
    r = report(moved, minus, "-o", tmp_path / "recorded")
    assert r.returncode == 0, r.stderr
    assert "g = (0.02, 0), 3 pairs of cells" in page_text(tmp_path / "recorded")
    gone = edited_bytes(moved, tmp_path / "gone.fits", b"SHEAR1  =", b"OLDSHR1 =")
    refused(tmp_path, "no_shear", [gone, minus], gone, "cell_9999.fits' is not found here: give it (--shear G1,G2)")
    r = report(gone, minus, "--shear", "0.02,0", "-o", tmp_path / "given")
    assert r.returncode == 0, r.stderr
    assert "g = (0.02, 0), 3 pairs of cells" in page_text(tmp_path / "given")
