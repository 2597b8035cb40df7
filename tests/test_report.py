"""platesynth report: one static offline page for a study, a dataset and an optimisation run, opened in Chromium."""

from __future__ import annotations

import re
import shutil
import subprocess

import numpy as np
import pytest
from typer.testing import CliRunner

from _study_world import offline_weights, tiny_study
from platesynth.cli import app
from platesynth.report import build_report, write_report
from platesynth.study.cache import stage_dir

runner = CliRunner()

# Injected before the page's own content: every error (script, resource) and console.error is written into the
# DOM, and after the load event the number of images and of those that failed to decode.
PROBE = """<script>
(function () {
  var root = document.documentElement;
  function note(text) { root.setAttribute('data-errors', (root.getAttribute('data-errors') || '') + text + '\\n'); }
  window.addEventListener('error', function (e) {
    note('error: ' + (e.message || (e.target && (e.target.src || e.target.href || e.target.tagName)) || '?'));
  }, true);
  window.addEventListener('unhandledrejection', function (e) { note('rejection: ' + e.reason); });
  var original = console.error;
  console.error = function () { note('console.error: ' + Array.prototype.join.call(arguments, ' ')); original.apply(console, arguments); };
  window.addEventListener('load', function () {
    var images = Array.prototype.slice.call(document.images);
    root.setAttribute('data-images', String(images.length));
    root.setAttribute('data-broken-images', String(images.filter(function (i) { return !i.complete || i.naturalWidth === 0; }).length));
    root.setAttribute('data-loaded', 'yes');
  });
})();
</script>"""


def chromium():
    for name in ("chromium", "chromium-browser"):
        if path := shutil.which(name):
            return path
    pytest.skip("headless Chromium not found (Debian: apt-get install chromium): the report's page is not opened")


def open_page(html_path, tmp_path, screenshot=None, size=(1280, 3200)):
    """Open a copy of the page with the probe in headless Chromium; return its DOM after load and the log."""
    text = html_path.read_text(encoding="utf-8")
    probed = tmp_path / f"probed-{html_path.name}"
    probed.write_text(text.replace("<head>", "<head>\n" + PROBE, 1), encoding="utf-8")
    arguments = [chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", "--no-first-run",
                 "--enable-logging=stderr", "--v=0", f"--user-data-dir={tmp_path / 'chromium-profile'}",
                 "--virtual-time-budget=10000", f"--window-size={size[0]},{size[1]}"]
    arguments += [f"--screenshot={screenshot}"] if screenshot else ["--dump-dom"]
    done = subprocess.run([*arguments, probed.as_uri()], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout, done.stderr


def assert_loads_cleanly(dom, log):
    assert 'data-loaded="yes"' in dom, "the load event never came"
    errors = re.search(r'data-errors="([^"]*)"', dom)
    assert errors is None, errors.group(1)
    assert 'data-broken-images="0"' in dom
    console = [line for line in log.splitlines() if ":CONSOLE" in line]
    assert console == [], console


def assert_offline(text):
    assert "<script" not in text and "<link" not in text and "@import" not in text
    outside = re.findall(r'(?:src|href)\s*=\s*"(?!data:|#)([^"]*)"', text)
    assert outside == []
    assert "url(" not in text.split("</style>")[0].split("<style>")[-1]


@pytest.fixture
def world(tmp_path_factory):
    return tiny_study(tmp_path_factory)


@pytest.fixture
def study_page(world):
    return write_report(world["out"])


def test_the_study_page_loads_in_chromium_and_shows_tables_and_pictures(world, study_page, tmp_path):
    text = study_page.read_text(encoding="utf-8")
    assert_offline(text)
    dom, log = open_page(study_page, tmp_path)
    assert_loads_cleanly(dom, log)
    assert dom.count("<table") >= 3
    for header in ("FD AlexNet", "count MAE (real)", "AP wells (test)"):
        assert header in dom
    for arm in ("high-S", "low-S"):
        assert arm in dom
    images = int(re.search(r'data-images="(\d+)"', dom).group(1))
    assert images >= 3 + 2 * 4 * 2 + 2  # photos, samples plain and outlined, radar charts
    assert 'id="outlines"' in dom and 'class="outlined"' in dom
    for section in ("samples", "tables", "radar", "counts", "worst", "time", "training"):
        assert f'id="{section}"' in dom

    shot = tmp_path / "study.png"
    open_page(study_page, tmp_path, screenshot=shot)
    from PIL import Image

    pixels = np.asarray(Image.open(shot).convert("RGB")).astype(int)
    assert pixels.std() > 20  # not blank
    background = (np.abs(pixels - 250).sum(axis=2) <= 6).mean()
    assert background < 0.9
    header = (np.abs(pixels - (38, 50, 56)).sum(axis=2) <= 6).mean()  # the title bar
    assert header > 0.01
    table_heads = (np.abs(pixels - (236, 239, 241)).sum(axis=2) <= 3).sum()  # the tables' header rows
    assert table_heads > 2000
    channels = pixels.max(axis=2) - pixels.min(axis=2)
    assert (channels > 80).mean() > 0.02  # photos and renders: saturated stain colours


def test_a_second_report_replaces_the_first_and_other_files_stay(world, study_page, tmp_path):
    assert write_report(world["out"]) == study_page
    other = tmp_path / "notes.html"
    other.write_text("<html>mine</html>")
    result = runner.invoke(app, ["report", str(world["out"]), "--out", str(other)])
    assert result.exit_code == 1 and "exists and is not an HTML report" in result.output
    assert other.read_text() == "<html>mine</html>"
    result = runner.invoke(app, ["report", str(world["out"]), "--out", str(other), "--overwrite"])
    assert result.exit_code == 0 and "platesynth study" in other.read_text()


def test_a_folder_without_anything_to_report_is_refused(tmp_path):
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "x.txt").write_text("x")
    result = runner.invoke(app, ["report", str(tmp_path / "empty")])
    assert result.exit_code == 1
    assert result.output.strip() == (f"error: {tmp_path / 'empty'}: holds no study, rendered dataset or optimisation "
                                     "run to report on")
    assert sorted(p.name for p in (tmp_path / "empty").iterdir()) == ["x.txt"]


def test_the_dataset_page(world, tmp_path):
    import json

    test_set = json.loads((world["out"] / "results.json").read_text())["test_render"]
    dataset = stage_dir(world["out"], "render", test_set) / "data"
    page = tmp_path / "dataset.html"
    result = runner.invoke(app, ["report", str(dataset), "--out", str(page), "--reference",
                                 str(world["inputs"] / "reference")])
    assert result.exit_code == 0, result.output
    text = page.read_text()
    assert_offline(text)
    assert "What was rendered" in text and "Plaques per well" in text and "Brisbane_plate2.png" in text
    dom, log = open_page(page, tmp_path)
    assert_loads_cleanly(dom, log)
    assert int(re.search(r'data-images="(\d+)"', dom).group(1)) == 3 + 2 * 2 + 1  # photos, samples, histogram


def test_the_optimisation_page(world, tmp_path):
    pytest.importorskip("optuna", reason="platesynth optimise needs Optuna: pip install 'platesynth[optimise]'")
    from platesynth.optimise import optimise

    photos = tmp_path / "photos"  # five: each part of the split needs two
    photos.mkdir()
    for path in [*(world["inputs"] / "reference").iterdir(), *(world["inputs"] / "photos").iterdir()]:
        shutil.copy(path, photos / path.name)
    with offline_weights(world):
        optimise(photos, tmp_path / "opt", preset="low", trials=2, count=2, size=(96, 72),
                 eval_count=2, seed=5)
    text = build_report(tmp_path / "opt")
    assert_offline(text)
    assert "Evaluation of start and best" in text and "Best trials (2 in all)" in text
    assert "history of the objective" in text and 'id="outlines"' not in text
    page = write_report(tmp_path / "opt")
    dom, log = open_page(page, tmp_path)
    assert_loads_cleanly(dom, log)
