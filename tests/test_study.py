"""platesynth study: a tiny study end to end, its tables against the stages' outputs, caching, refusals."""

from __future__ import annotations

import csv
import json
import math

import pytest
import yaml
from typer.testing import CliRunner

from _study_world import ADDED_ARMS, ARMS, offline_weights, study_data, tiny_study, write_study
from platesynth.cli import app
from platesynth.errors import ParameterError
from platesynth.study import load_study, parse_study, run_study
from platesynth.study.cache import fingerprint, stage_dir, stage_key
from platesynth.study.tables import build_tables, cell

runner = CliRunner()


@pytest.fixture
def world(tmp_path_factory):
    return tiny_study(tmp_path_factory)


def stage_result(out, kind, key):
    return json.loads((stage_dir(out, kind, key) / "result.json").read_text())["result"]


def results(out):
    return json.loads((out / "results.json").read_text())


def test_the_study_runs_every_stage_once(world):
    result = world["result"]
    # 3 datasets + the test set; 3 measurements, trainings and evaluations
    kinds = [name.split(":")[0] for name in result.ran]
    assert sorted(kinds) == sorted(["render"] * 4 + ["measure"] * 3 + ["train"] * 3 + ["evaluate"] * 3)
    assert result.cached == [] and result.failed == {}
    out = world["out"]
    for name in ("study.json", "results.json", "radar_wells.svg", "radar_plaques.png", "tables/tables.md"):
        assert (out / name).is_file(), name
    assert json.loads((out / ".platesynth-output").read_text())["kind"] == "study"


def test_tables_hold_the_stage_outputs(world):
    out = world["out"]
    described = results(out)
    tables = {name: json.loads((out / "tables" / f"{name}.json").read_text()) for name in ("datasets", "wells", "plaques")}
    assert build_tables(described) == tables  # the files are what the stage results give
    for arm in described["arms"]:
        rows = {name: next(r for r in table["rows"] if r["arm"] == arm["name"]) for name, table in tables.items()}
        measures = [stage_result(out, "measure", r["keys"]["measure"]) for r in arm["replicates"] if r["keys"]["measure"]]
        evaluations = [stage_result(out, "evaluate", r["keys"]["evaluate"]) for r in arm["replicates"]]
        for key in ("fd_alexnet", "dnf", "entropy_matched", "fd_wells"):
            expected = [m[key] for m in measures]
            assert rows["datasets"]["values"][key]["values"] == pytest.approx(expected)
            assert rows["datasets"]["values"][key]["mean"] == pytest.approx(sum(expected) / len(expected))
        maes = [e["counts"]["mae"] for e in evaluations]
        assert rows["plaques"]["values"]["count_mae"]["mean"] == pytest.approx(sum(maes) / len(maes))
        assert rows["wells"]["values"]["ap_wells_test"]["values"] == pytest.approx(
            [e["test"]["wells"]["0.5"]["ap_mean"] for e in evaluations])
        assert rows["plaques"]["values"]["iou_r_plaques_test"]["values"] == pytest.approx(
            [e["test"]["plaques"]["0.5"]["iou_r_mean"] for e in evaluations])
        # the count MAE is that of the per-well table the evaluation wrote
        for replicate, evaluation in zip(arm["replicates"], evaluations):
            with (stage_dir(out, "evaluate", replicate["keys"]["evaluate"]) / "wells.csv").open() as handle:
                scored = [r for r in csv.DictReader(handle) if r["count"] != ""]
            mae = sum(abs(float(r["predicted"]) - float(r["count"])) for r in scored) / len(scored)
            assert evaluation["counts"]["mae"] == pytest.approx(mae)
            assert evaluation["counts"]["n_wells"] == len(scored)
        if len(arm["replicates"]) > 1:  # mean ± sd over seeds
            values = rows["plaques"]["values"]["count_mae"]["values"]
            mean = sum(values) / len(values)
            sd = math.sqrt(sum((v - mean) ** 2 for v in values) / (len(values) - 1))
            assert rows["plaques"]["values"]["count_mae"]["sd"] == pytest.approx(sd)
            assert " ± " in cell(rows["plaques"]["values"]["count_mae"], 2)
    # the CSV and Markdown hold the same numbers
    with (out / "tables" / "plaques.csv").open() as handle:
        for row in csv.DictReader(handle):
            summary = next(r for r in tables["plaques"]["rows"] if r["arm"] == row["arm"])["values"]["count_mae"]
            assert float(row["count_mae"]) == pytest.approx(summary["mean"])
            assert cell(summary, 2) in (out / "tables" / "plaques.md").read_text()


def test_a_rerun_does_no_work(world):
    out = world["out"]
    stamps = {p: p.stat().st_mtime_ns for p in (out / "stages").rglob("*") if p.is_file()}
    with offline_weights(world):
        result = runner.invoke(app, ["study", str(world["study_file"]), "--out", str(out), "--json"])
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["ran"] == [] and report["failed"] == {}
    assert len(report["cached"]) == 13
    assert {p: p.stat().st_mtime_ns for p in (out / "stages").rglob("*") if p.is_file()} == stamps


def test_an_added_arm_does_only_its_own_work(world, tmp_path):
    from platesynth.data.executor import ProcessExecutor

    study_file = write_study(tmp_path / "more.yaml", ARMS + ADDED_ARMS, world["inputs"])
    with offline_weights(world):
        result = run_study(load_study(study_file), world["out"], executor=ProcessExecutor(2), inputs=(study_file,))
    assert result.failed == {}
    described = {arm["name"]: arm for arm in results(world["out"])["arms"]}
    own = {f"{kind}:{key}" for name in ("medium-S", "mix") for r in described[name]["replicates"]
           for kind, key in r["keys"].items() if key is not None}
    assert sorted(result.ran) == sorted(own)
    assert len(own) == 6  # medium: render, measure, train, evaluate; the mix: train, evaluate
    assert described["mix"]["replicates"][0]["measure"] is None
    mix_training = stage_result(world["out"], "train", described["mix"]["replicates"][0]["keys"]["train"])
    config = json.loads((stage_dir(world["out"], "train", described["mix"]["replicates"][0]["keys"]["train"])
                         / "model" / "config.json").read_text())
    assert mix_training["epochs"] == 1 and config["training"]["mix"] == [0.5, 0.5]
    rows = {row["arm"]: row for row in json.loads((world["out"] / "tables" / "plaques.json").read_text())["rows"]}
    assert set(rows) == {"high-S", "low-S", "medium-S", "mix"}


def test_keys_follow_what_a_stage_depends_on(tmp_path):
    assert stage_key("train", {"a": 1, "b": [2]}) == stage_key("train", {"b": [2], "a": 1})
    assert stage_key("train", {"a": 1}) != stage_key("train", {"a": 2}) != stage_key("evaluate", {"a": 2})
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "x.png").write_bytes(b"1")
    before = fingerprint(tmp_path / "d")
    (tmp_path / "d" / ".platesynth.lock").write_bytes(b"")  # hidden files do not count
    assert fingerprint(tmp_path / "d") == before
    (tmp_path / "d" / "x.png").write_bytes(b"2")
    assert fingerprint(tmp_path / "d") != before


def _bad(data, change):
    data = json.loads(json.dumps(data))
    change(data)
    return data


CASES = [
    (lambda d: d.update(colour=1), "colour: unknown field"),
    (lambda d: d["arms"][0].pop("count"), "arms[0]: count is required"),
    (lambda d: d["arms"].append({"name": "m", "mix": {"hgih-S": 0.5, "low-S": 0.5}}),
     "arms[2].mix: unknown arm 'hgih-S' (the rendered arms are high-S, low-S)"),
    (lambda d: d["arms"].append({"name": "m", "mix": {"real": 0.1, "low-S": 0.9}}), "'real' needs real_training"),
    (lambda d: d["arms"].append(dict(d["arms"][0])), "arms[2].name: 'high-S' appears twice"),
    (lambda d: d["arms"][0].update(preset="hgih"), "bad.yaml: arms[0] (high-S): unknown preset 'hgih'"),
    (lambda d: d["arms"][0].update(overrides={"stain.hue_dg": 3}), "arms[0] (high-S): override stain.hue_dg: unknown parameter (did you mean stain.hue_deg?)"),
    (lambda d: d.update(size="12x"), "size: expected WIDTHxHEIGHT"),
    (lambda d: d["recipe"].update(patch="65x65"), "bad.yaml: recipe: patch 65x65 must be a positive multiple"),
    (lambda d: d["recipe"].update(model={"chanels": [8]}), "bad.yaml: recipe.model: chanels: unknown field"),
    (lambda d: d.update(reference="nowhere"), "reference: "),
    (lambda d: d["evaluation"].update(images=d["reference"]), "PR8_plate3.png not found in"),
    (lambda d: d["recipe"].update(device="cuda:7"), "cuda"),
]


@pytest.mark.parametrize(("change", "message"), CASES)
def test_a_bad_study_is_refused_in_one_line_before_writing(world, tmp_path, change, message):
    path = tmp_path / "bad.yaml"
    path.write_text(json.dumps(_bad(study_data(ARMS, world["inputs"]), change)), encoding="utf-8")  # JSON is YAML
    with offline_weights(world):
        result = runner.invoke(app, ["study", str(path), "--out", str(tmp_path / "out")])
    assert result.exit_code == 1
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], result.output
    assert not (tmp_path / "out").exists()


def test_the_output_is_claimed(world, tmp_path):
    (tmp_path / "ds").mkdir()
    (tmp_path / "ds" / "manifest.json").write_text("{}")
    with offline_weights(world):
        result = runner.invoke(app, ["study", str(world["study_file"]), "--out", str(tmp_path / "ds")])
    assert result.exit_code == 1 and "holds a rendered dataset, not a study" in result.output


def test_the_shipped_study_is_valid():
    from pathlib import Path

    spec = parse_study(yaml.safe_load((Path(__file__).parents[1] / "studies" / "paper.yaml").read_text()),
                       "paper.yaml", Path(__file__).parents[1] / "studies")
    names = {arm.name for arm in spec.arms}
    assert {"high-S", "high-L", "medium-S", "medium-L", "low-S", "low-L"} <= names
    with pytest.raises(ParameterError, match="unknown field"):
        parse_study({"reference": "x", "arms": [{"name": "a", "preset": "high", "count": 1, "size": 3}]})


def test_overwriting_a_study_removes_its_files_only(tmp_path):
    from platesynth.outputs import claim_output, folder_kind

    study = tmp_path / "s"
    (study / "stages" / "render" / "k" / "data").mkdir(parents=True)
    (study / "tables").mkdir()
    for name in ("study.json", "results.json", "report.html", "radar_wells.svg", "stages/render/k/data/a.png",
                 "tables/plaques.md", "mine.txt"):
        (study / name).write_text("x")
    assert folder_kind(study) == "study"
    with claim_output(study, "dataset", overwrite=True) as claim:
        claim.take()
    assert sorted(p.name for p in study.iterdir()) == [".platesynth-output", "mine.txt"]
