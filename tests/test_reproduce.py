"""``diracvi reproduce --quick``: every file is written and the paper's claims hold."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from typer.testing import CliRunner

from diracvi.cli import app
from diracvi.reproduce import FIGURES
from diracvi.reproduce.report import fmt

ROUND_OFF = 1e-12


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("repro")
    result = CliRunner().invoke(app, ["reproduce", "--out", str(out), "--quick"])
    assert result.exit_code == 0, result.output
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    return out, summary, result.output


def test_every_figure_is_a_non_empty_png(run):
    out, summary, _ = run
    for name in FIGURES:
        data = (out / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n", name
        assert len(data) > 10_000, name  # a drawn figure, not an empty canvas
    assert set(summary["figures"]) == set(FIGURES)


def test_summary_has_the_expected_keys(run):
    _, summary, _ = run
    assert summary["quick"] is True
    # timings are reported with the dispatch mode they were taken in (diracvi.runtime.dispatch)
    assert summary["machine"]["cpu_dispatch"] == "synchronous"
    assert set(summary["examples"]) == {"spring_chain", "rlc"}
    for s in summary["examples"].values():
        for key in (
            "max_position_difference",
            "constraint_deviation",
            "energy",
            "timing",
            "discretizations",
            "paper",
            "shared",
            "ports",
        ):
            assert key in s
        assert set(s["max_position_difference"]) == {
            "interconnected_vs_monolithic",
            "interconnected_vs_reduced",
            "monolithic_vs_reduced",
        }
        for key in ("initial", "final", "min", "max", "relative_oscillation", "relative_drift"):
            assert key in s["energy"]["interconnected"]
        t = s["timing"]
        for key in (
            "reduced_s",
            "monolithic_s",
            "interconnected_s",
            "ratio_interconnected_to_reduced",
            "protocol",
        ):
            assert key in t
        assert t["ratio_interconnected_to_reduced"] == pytest.approx(
            t["interconnected_s"] / t["reduced_s"]
        )
        assert t["repeats"] == 20  # --quick
    assert "long_run" in summary["examples"]["spring_chain"]
    assert "resistor_sign" in summary["examples"]["rlc"]
    assert any("resistor sign" in d for d in summary["deviations"])


def test_paper_numbers_are_carried_verbatim(run):
    _, summary, _ = run
    spring, rlc = (
        summary["examples"]["spring_chain"]["timing"],
        summary["examples"]["rlc"]["timing"],
    )
    assert (spring["paper"]["monolithic_s"], spring["paper"]["interconnected_s"]) == (
        0.0028,
        0.0029,
    )
    assert (rlc["paper"]["monolithic_s"], rlc["paper"]["interconnected_s"]) == (8.16e-4, 8.51e-4)
    assert summary["examples"]["spring_chain"]["steps"] == 1000
    assert summary["examples"]["spring_chain"]["dt"] == 0.01
    assert summary["examples"]["rlc"]["steps"] == 400
    assert summary["examples"]["rlc"]["dt"] == 0.1


@pytest.mark.parametrize("example", ["spring_chain", "rlc"])
def test_interconnected_equals_monolithic_and_keeps_the_constraint(run, example):
    s = run[1]["examples"][example]
    for value in s["max_position_difference"].values():
        assert value <= ROUND_OFF
    assert s["max_energy_difference"]["interconnected_vs_reduced"] <= ROUND_OFF
    assert s["constraint_deviation"]["position_max"] <= ROUND_OFF
    assert s["constraint_deviation"]["discrete_interaction_max"] <= ROUND_OFF
    assert s["constraint_deviation"]["discrete_all_max"] <= ROUND_OFF
    assert s["interaction_constraints"]  # the interaction rows were found, not skipped


@pytest.mark.parametrize("example", ["spring_chain", "rlc"])
def test_observed_orders_are_one_and_two(run, example):
    rules = run[1]["examples"][example]["discretizations"]
    assert abs(rules["retraction"]["fitted_order"] - 1.0) < 0.1
    assert abs(rules["midpoint"]["fitted_order"] - 2.0) < 0.1


def test_spring_energy_oscillates_without_drift(run):
    s = run[1]["examples"]["spring_chain"]
    long = s["long_run"]
    assert long["steps"] == 10_000  # --quick
    assert long["energy"]["relative_oscillation"] < 0.02
    # over 10^4 steps the first and last tenth average to the same energy
    assert abs(long["energy"]["relative_drift"]) < 1e-3


def test_resistor_sign(run):
    sign = run[1]["examples"]["rlc"]["resistor_sign"]
    assert sign["physical_energy_nonincreasing"]
    assert sign["physical"]["final"] < 1e-2 * sign["physical"]["initial"]
    assert sign["paper_printed"]["final"] > 1e3 * sign["paper_printed"]["initial"]


def test_reports_link_or_embed_every_figure_and_state_deviations(run):
    out, summary, _ = run
    md = (out / "report.md").read_text(encoding="utf-8")
    page = (out / "report.html").read_text(encoding="utf-8")
    for name in FIGURES:
        assert f"]({name})" in md
    assert len(re.findall(r'src="data:image/png;base64,', page)) == len(FIGURES)
    for text in (md, page):
        assert "resistor sign" in text
        assert "0.0028" in text and "8.160e-04" in text  # the paper's timings
        assert "Quick run" in text
    spring = summary["examples"]["spring_chain"]
    assert fmt(spring["timing"]["reduced_s"]) in md


def test_progress_is_plain_text_off_a_terminal(run):
    output = run[2]
    assert "timing the interconnected model" in output
    assert "\x1b[" not in output  # no cursor control when not a TTY
    assert f"wrote {len(FIGURES)} figures, summary.json, report.md and report.html" in output


def test_existing_file_as_out_is_refused(tmp_path):
    path = tmp_path / "file"
    path.write_text("x")
    result = CliRunner().invoke(app, ["reproduce", "--out", str(path), "--quick"])
    assert result.exit_code == 2
    assert str(path) in result.output


def test_energy_stats_definition():
    from diracvi.reproduce.metrics import energy_stats

    e = 2.0 + 0.1 * np.sin(np.linspace(0, 20 * np.pi, 1000))
    stats = energy_stats(e)
    assert stats["initial"] == 2.0
    assert stats["relative_oscillation"] == pytest.approx(0.1, rel=1e-3)
    assert abs(stats["relative_drift"]) < 1e-3
    drifting = energy_stats(np.linspace(1.0, 2.0, 1000))
    assert drifting["relative_drift"] == pytest.approx(0.9, rel=1e-2)


def test_document_escapes_html_and_renders_inline_code(tmp_path):
    from diracvi.reproduce.document import Document

    doc = Document("t")
    doc.paragraph("a <b> & `x < y` **bold**")
    doc.table(["a|b"], [["1"]])
    page = doc.to_html()
    assert "a &lt;b&gt; &amp; <code>x &lt; y</code> <strong>bold</strong>" in page
    assert "| a\\|b |" in doc.to_markdown()


def test_report_names_the_solver_that_ran(run):
    out, summary, _ = run
    md = (out / "report.md").read_text(encoding="utf-8")
    for key in ("spring_chain", "rlc"):
        ran = summary["examples"][key]["solver"]["interconnected"]
        assert ran and f"`{ran}`" in md
    if all(
        summary["examples"][k]["solver"]["interconnected"] == "affine step map"
        for k in ("spring_chain", "rlc")
    ):
        assert "the next confirms it" not in md and "affine step map" in md


def test_html_report_has_no_literal_emphasis_markers(run):
    page = (run[0] / "report.html").read_text(encoding="utf-8")
    body = re.sub(r"<style>.*?</style>|<img [^>]*>", "", page, flags=re.S)
    assert not re.search(r"\*[^*\s<>][^*<>]*\*", body), "literal *…* in the HTML"


def test_document_renders_emphasis_but_not_lone_asterisks():
    from diracvi.reproduce.document import Document

    doc = Document("t")
    doc.paragraph("an *emphasised* word, a * b, and **bold**")
    page = doc.to_html()
    assert "<em>emphasised</em>" in page and "a * b" in page
    assert "<strong>bold</strong>" in page


def test_long_energy_envelope_keeps_the_extremes():
    from diracvi.reproduce.figures import envelope

    t = np.arange(100_000) * 0.01
    e = 1.0 + 1e-3 * np.sin(7.0 * t)
    mids, low, high = envelope(t, e, windows=400)
    assert len(mids) == 400
    assert low.min() == e.min() and high.max() == e.max()
    assert np.all(low <= high) and np.all(np.diff(mids) > 0)
