"""Every page read at a glance. Each page the commands write (diagnosis of a turntable
set, with an effect added, and of a stream; validation; thermal; noise; field drift; lot), built from the demo's data,
read in headless Chromium at a laptop's and a phone's width (tests/browser.py: tables rectangular, no number split,
no text on a figure, figures using their column), each check failing on a page with the defect planted;
no text of any figure overlaps another or sits on a marker, nothing shrinks below 8 px in a 1280 px
window (tests/page_layout.py says why without a browser), every page opens with a verdict per sensor
and the next command, in one stylesheet; the validation's bars on a log scale with their floor; the
diagnosis's rows that say nothing folded away; the noise table in one unit system."""
from __future__ import annotations

import html
import json
import re

import matplotlib.pyplot as plt
import numpy as np
import pytest
from browser import WIDTHS, chromium, page_problems
from cli_helpers import run
from page_layout import figure_problems, figures_checked, html_problems

from simucal import api
from simucal.api import demo_run
from simucal.api.diagnosing import diagnosis_report as diagnose
from simucal.handheld.simulate import HandheldScenario, write_handheld
from simucal.io import calibration
from simucal.report import page as page_module
from simucal.report.numbers import eng
from simucal.report.console import noise_lines, noise_verdicts, validation_next
from simucal.report.field_html import field_page
from simucal.report.html import render
from simucal.report.history_html import history_page
from simucal.report.lot_html import lot_page
from simucal.report.noise_html import noise_page
from simucal.report.thermal_html import thermal_page
from simucal.turntable.lot import write_lot
from store_helpers import unit_files
from simucal.turntable.simulate import SCENARIOS, write
from simucal.api.validating import html_page, lines, validation_report as validate


@pytest.fixture(scope="module")
def pages(tmp_path_factory):
    """{name: (html, figure problems, figures)} of every kind of page, and "out": their data's folder. The
    demo's unit over temperature, its noise, its hidden effect on the Table 1 plan, a hand-placed stream."""
    out = tmp_path_factory.mktemp("pages")
    said = []
    demo_run.thermal(out, 0, said.append)
    rows = said[said.index(next(x for x in said if "validate at 35 degC" in x)) + 2:]  # the demo's table, whole
    assert [r.strip().split("  ")[0] for r in rows[:2]] == [demo_run._label(c) for c in validate(
        out / "thermal_calibration.json", out / "thermal_35")["checks"].values() for c in c[:1]], rows
    demo_run.noise(out, 0, lambda _: None)
    sc = SCENARIOS["paper"]()
    sc.plan, sc.rate_hz, sc.static_s, sc.acc_effects = "table1", 20.0, 5.0, dict(demo_run.HIDDEN)
    write(out / "loop", sc, 0)
    write_handheld(out / "stream", HandheldScenario(poses=14, rest_s=10.0), 1)
    api.simulate("field", seed=3).write(out / "field")
    api.calibrate_each(write_lot(out / "lot", 3, seed=3), out / "lot_calibrations")
    thermal_cal = out / "thermal_calibration.json"
    lot_cal = sorted((out / "lot_calibrations").glob("*.json"))[0]
    store = api.Store(out / "lab.db")
    for month, path in enumerate(unit_files(lot_cal, out / "history", 1, 4, drifting={0})["SN-0000"]):
        store.add(path, time=f"2026-{1 + 3 * month:02d}-01")
    gyro = calibration.load(lot_cal).gyro
    (out / "spec.json").write_text(json.dumps({"format": "simucal.limits/1", "limits": {"gyro.b_z": {
        "min": gyro.params["b_z"] - 300 * gyro.std["b_z"], "max": gyro.params["b_z"] + 300 * gyro.std["b_z"],
        "unit": gyro.param_units["b_z"]}}}))
    (out / "validation.json").write_text(json.dumps(validate(out / "thermal_calibration_25.json", out / "thermal_35")))
    (out / "thermal_validation.json").write_text(json.dumps(validate(thermal_cal, out / "thermal_35")))
    build = {
        "diagnosis": lambda: render(diagnose(out / "loop")),
        "diagnosis --add": lambda: render(diagnose(out / "loop", add=tuple(demo_run.HIDDEN))),
        "diagnosis of a stream": lambda: render(diagnose(out / "stream")),
        "validation": lambda: html_page(json.loads((out / "validation.json").read_text())),
        "thermal": lambda: thermal_page(calibration.load(thermal_cal), [validate(thermal_cal, out / "thermal_35")],
                                        str(thermal_cal)),
        "noise": lambda: noise_page(json.loads((out / "noise.json").read_text())),
        "field": lambda: field_page(api.calibrate(out / "field", method="field"), "field_calibration.json"),
        "lot": lambda: lot_page(api.lot(out / "lot_calibrations")),
        "history": lambda: history_page(store.history("SN-0000", spec=out / "spec.json")),
        "certificate": lambda: api.certificate(thermal_cal, validation=out / "thermal_validation.json"),
    }
    made = {"out": out}
    for name, f in build.items():
        with figures_checked() as (problems, figures):
            made[name] = (f(), problems, figures)
    return made


@pytest.mark.slow
def test_no_text_overlaps_on_any_page(pages):
    made = {k: v for k, v in pages.items() if k != "out"}
    found = [f"{name}: {p}" for name, (page, problems, _) in made.items() for p in problems + html_problems(page)]
    assert not found, "\n".join(found)
    assert all(figs for name, (_, _, figs) in made.items() if name != "certificate")  # checked through its figures
    assert not made["certificate"][2]  # a certificate is its tables: text the browser lays out


def test_the_check_finds_what_it_looks_for():
    """Two labels on one spot, a label on a marker, text too small: each found (the test above can fail)."""
    fig, ax = plt.subplots(figsize=(4, 3))
    ax.scatter([0.5], [0.5], s=60)
    ax.text(0.5, 0.5, "on the marker", transform=ax.transAxes)
    ax.text(0.1, 0.9, "one label", transform=ax.transAxes)
    ax.text(0.1, 0.9, "another", transform=ax.transAxes)
    ax.set_xlabel("tiny", fontsize=4)
    found = figure_problems(fig, 90)
    fig, ax = plt.subplots(figsize=(4, 3))
    ax.plot([0, 1], [0.3, 0.3], ls="--")  # a floor line through a bar's value
    ax.text(0.2, 0.3, "on the line", va="center")
    found += figure_problems(fig, 90)
    plt.close("all")
    assert any("'one label' overlaps 'another'" in p for p in found)
    assert any("'on the marker' under a marker" in p for p in found)
    assert any("below 8 px" in p for p in found)
    assert any("'on the line' on a line of the plot" in p for p in found)
    assert html_problems("<h1>x</h1><p class='verdict ok'>acc</p><h2>acc</h2>") == [
        "the page does not open with the verdicts and the next command (before its first section)"]


def test_every_page_in_one_stylesheet_opens_with_verdicts_and_next(pages):
    for name, (page, _, _) in ((k, v) for k, v in pages.items() if k not in ("out", "lot")):  # a lot's: per unit
        head = page.split("<h2", 1)[0]
        assert page.count(page_module.STYLE) == 1, name
        sensors = re.findall(r"<p class='verdict (?:ok|bad)'><b>(acc|gyro)", head)
        assert set(sensors) == {"acc", "gyro"}, (name, sensors)
        assert re.search(r"<p class='next'>Next: <code>simucal \w+ ", head), name


def test_validation_bars_on_a_log_scale_with_the_floor(pages):
    _, _, (fig,) = pages["validation"]
    drawn = [ax for ax in fig.axes if ax.get_visible()]
    assert drawn and all(ax.get_yscale() == "log" for ax in drawn)
    floors = [t.get_text() for ax in drawn for t in ax.texts if t.get_text().startswith("floor ")]
    assert len(floors) == len(drawn)  # every check of the demo's set has a floor
    for ax in drawn:  # the calibrated bar (1e-3 of the nominal one and less) is inside the axis, not below it
        lo, hi = ax.get_ylim()
        assert all(lo < p.get_height() < hi for p in ax.patches)


def test_validation_console_and_page_say_the_same(pages):
    page = pages["validation"][0]
    rep = json.loads((pages["out"] / "validation.json").read_text())
    cmd = validation_next(rep)[0]
    assert f"next: {cmd}" in list(lines(rep)) and f"Next: <code>{cmd}</code>" in page
    for s, v in rep["verdict"].items():
        assert f"<b>{s}: {v}</b>" in page


def test_the_diagnosis_folds_the_rows_that_say_nothing(pages):
    for name in ("diagnosis", "diagnosis of a stream"):
        page = pages[name][0]
        open_part = re.sub(r"<details>.*?</details>", "", page, flags=re.S)
        assert "no input for it in these data" in page and "no input for it" not in open_part, name
        rows = open_part.count("<tr>")
        assert rows < page.count("<tr>") / 2, (name, rows, page.count("<tr>"))


def test_the_noise_page_one_unit_system_and_the_consoles_verdicts(pages):
    page = pages["noise"][0]
    acc = page.split("<h2>acc</h2>", 1)[1].split("</table>", 1)[0]
    acc = re.sub(r"<img [^>]*>", "", acc)  # an embedded figure's base64 may spell anything
    units = re.findall(r"<th>[^<(]+\(([^)]+\)?)\)</th>", acc)
    assert len(units) == 5 and all(u.startswith("ug") for u in units), units
    assert "m/s" not in acc and "not seen (&lt;" in acc
    assert [f.axes[0].get_ylabel() for f in pages["noise"][2]] == ["Allan deviation (ug)", "Allan deviation (deg/h)"]
    cells = [re.sub(r"<span class='n'>([^<]*)</span>", r"\1", c) for c in re.findall(r"<td>(.*?)</td>", page)]
    # every term: value +- std, or not seen with its bound
    assert all(re.fullmatch(r"[xyz]|\S+ &plusmn; \S+|not seen \(&lt; \S+, 95 %\)|record too short.*", c)
               for c in cells), cells
    report = json.loads((pages["out"] / "noise.json").read_text())
    console = list(noise_lines(report))
    assert len(noise_verdicts(report)) == 2
    for _, text in noise_verdicts(report):
        assert text in console and f"<b>{html.escape(text)}</b>" in page


@pytest.fixture(scope="module")
def browser():
    with chromium() as driver:
        yield driver


@pytest.mark.slow
@pytest.mark.parametrize("width", WIDTHS.values(), ids=WIDTHS.keys())
def test_every_page_in_chromium(pages, browser, width, tmp_path):
    """Every page kind laid out by Chromium at a laptop's and a phone's width passes tests/browser.py's checks."""
    found = [f"{name}: {p}" for name, made in pages.items() if name != "out"
             for p in page_problems(browser, made[0], width, tmp_path)]
    assert not found, "\n".join(found)


def _planted(body: str) -> str:
    """A page in the pages' shell with `body`, a figure of 1170 px (the pages' own width) before it."""
    fig, ax = plt.subplots(figsize=(page_module.FULL_IN, 3), layout="constrained")
    ax.plot([0, 1], [0, 1])
    return page_module.page("planted", "planted", [(True, "acc: planted")], "simucal noise X", body=[
        page_module.png(fig), body])


@pytest.mark.slow
@pytest.mark.parametrize("body, found", [
    ("<table><tr><th>a</th><th>b</th></tr><tr><td>1</td><td>2</td><td>3</td></tr></table>",
     "table 1 (ab) is ragged: its rows have 2, 3 columns"),
    ("<p style='margin-top:-120px'>a paragraph laid over the figure</p>",
     "the text 'a paragraph laid over the figure' lies on figure 1"),
    ("<table><tr><td style='width:40px;max-width:40px'>6.257e-06</td></tr></table>",
     "the number 6.257e-06 is split across lines"),
    ("<div style='width:600px'><img src='data:image/png;base64,iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR4"
     "2mP8z8BQDwAEhQGAhKmMIQAAAABJRU5ErkJggg==' style='width:200px'></div>",
     "figure 2 is 200 px wide in a 600 px column"),
], ids=["ragged table", "text on a figure", "split number", "figure not using its width"])
def test_each_browser_check_finds_its_defect(browser, tmp_path, body, found):
    """Each check fails on a page with its defect planted (and only the planted one: the shell itself passes)."""
    assert page_problems(browser, _planted(""), WIDTHS["desktop"], tmp_path) == []
    problems = page_problems(browser, _planted(body), WIDTHS["desktop"], tmp_path)
    assert len(problems) == 1 and problems[0].startswith(found), problems


@pytest.mark.parametrize("value, text", [(145.0, "145"), (100.0, "100"), (505.2, "505"), (1.452e-4, "145e-6"),
                                         (6.2573e-6, "6.26e-6"), (999.7, "1e3"), (-5e-4, "-500e-6"), (0.0, "0"),
                                         (12, "12"), (None, "-"), (9.8e-7, "980e-9")])
def test_one_number_format(value, text):
    """Engineering notation: the exponent a multiple of 3, never "1e+02"."""
    assert eng(value) == text


def test_the_validation_bars_read_as_the_table(pages):
    """Each bar's value and each floor is written as the table writes it (one helper, the same digits)."""
    page, _, (fig,) = pages["validation"]
    table = page.split("<table>", 1)[1]
    cells = re.findall(r"<span class='n'>([^<]*)</span>", table)
    drawn = [t.get_text().removeprefix("floor ") for ax in fig.axes if ax.get_visible() for t in ax.texts]
    assert drawn and sorted(drawn) == sorted(c for c in cells if c != "-"), (drawn, cells)


@pytest.mark.parametrize("ratio", [0.5, 1.2, 2.0, 5.0])
def test_the_floor_never_crosses_a_bars_value(ratio):
    """The floor at any height about the calibrated bar's top (1.2: where its value is written) crosses no text."""
    fig, ax = plt.subplots(figsize=(3.1, 3.4), layout="constrained")
    page_module.log_bars(ax, ["nominal", "calibrated"], [145.0, 1.0], ratio, "ug")
    found = figure_problems(fig, page_module.DPI)
    plt.close(fig)
    assert not found, found


def test_the_thermal_bands_are_seen(pages):
    """Each 68 % band is drawn 3 px thick or more (its area over its width, in pixels): on an axis of its own (less
    the fit), not a hair along the curve."""
    bands = [c for f in pages["thermal"][2] for ax in f.axes for c in ax.collections if c.get_label().startswith("fit")]
    assert bands
    for band in bands:
        x, y = band.get_transform().transform(band.get_paths()[0].vertices).T
        thick = abs(np.dot(x, np.roll(y, 1)) - np.dot(y, np.roll(x, 1))) / 2 / np.ptp(x)
        assert thick >= 3, (band.axes.get_title(), thick)


def test_the_thermal_table_names_what_each_misalignment_is(pages):
    """The accelerometer's theta_ij and the gyro's phi_ij each with its meaning: an axis tilted toward another."""
    page = pages["thermal"][0]
    for name in ("theta_yx", "phi_yx"):
        row = re.search(rf"<tr><td>{name}</td><td>([^<]*)</td>", page)
        assert row and "axis tilted toward x" in row.group(1), name


@pytest.mark.slow
def test_the_noise_pages_next_is_the_consoles(pages, tmp_path):
    """With --kalibr the page proposes what the console proposes (a calibration weighed by the curves), not the
    command just run."""
    r = run("noise", pages["out"] / "still", "-o", tmp_path / "n.json", "--html", tmp_path / "n.html",
            "--kalibr", tmp_path / "imu.yaml")
    assert r.exit_code == 0, r.output
    said = next(x.removeprefix("next: ") for x in r.output.splitlines() if x.startswith("next: "))
    assert "--kalibr" not in said and f"Next: <code>{html.escape(said)}</code>" in (tmp_path / "n.html").read_text()
