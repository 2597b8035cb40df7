"""platesynth optimise: the search space, the split, and tiny runs (complete, deterministic, resumed, refused)."""

from __future__ import annotations

import json

import pytest

from platesynth.errors import OutputError, ParameterError
from platesynth.optimise import default_space, load_space, optimise, split_reference
from platesynth.optimise.space import LEFT_OUT, SEARCHED_SECTIONS
from platesynth.scene import load_config
from platesynth.scene.catalogue import parameter_table

pytest.importorskip("optuna", reason="platesynth optimise needs Optuna: pip install 'platesynth[optimise]'")

TINY = {"count": 3, "size": (128, 100), "eval_count": 3, "well_size": 48, "seed": 5}


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """Eight of the shared plate photos (two groups), shrunk to 304 px wide in a temporary folder."""
    from PIL import Image

    from conftest import shared_path

    plates = shared_path("data", "plaque12", "plates")
    folder = tmp_path_factory.mktemp("reference")
    for name in [f"Brisbane_plate{i}.jpg" for i in (2, 3, 4, 5)] + [f"PR8_plate{i}.jpg" for i in (1, 2, 3, 4)]:
        with Image.open(plates / name) as image:
            image.convert("RGB").resize((304, 236), Image.Resampling.LANCZOS).save(folder / f"{name[:-4]}.png")
    return folder


@pytest.fixture(scope="module")
def weights(tmp_path_factory):
    """The developers' AlexNet weights, offline, no Inception weights (module-wide, for the module's runs)."""
    import os

    from conftest import shared_path

    saved = {k: os.environ.get(k) for k in ("PLATESYNTH_WEIGHTS_DIR", "PLATESYNTH_OFFLINE", "TORCH_HOME")}
    os.environ["PLATESYNTH_WEIGHTS_DIR"] = str(shared_path("weights", "alexnet_features-7be5be79.pth").parent)
    os.environ["PLATESYNTH_OFFLINE"] = "1"
    os.environ["TORCH_HOME"] = str(tmp_path_factory.mktemp("torch-home"))
    yield
    for key, value in saved.items():
        if value is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = value


@pytest.fixture(scope="module")
def run_of_four(reference, weights, tmp_path_factory, one_torch_thread):
    """A tiny run of 4 trials from `low`."""
    out = tmp_path_factory.mktemp("opt") / "four"
    return optimise(reference, out, preset="low", trials=4, **TINY)


def _trials(out):
    rows = json.loads((out / "trials.json").read_text())
    return [{k: v for k, v in row.items() if k != "seconds"} for row in rows]


# --------------------------------------------------------------------------------------------- space and split


def test_default_space_is_the_look_within_valid_ranges():
    start = load_config("low")
    space = default_space(start)
    table = {row["name"]: row for row in parameter_table()}
    assert space.parameters
    for parameter in space.parameters:
        assert parameter.name.split(".")[0] in SEARCHED_SECTIONS and parameter.name not in LEFT_OUT
        low, high = table[parameter.name]["range"]
        assert low <= parameter.low < parameter.high <= high
    # the start's own values reproduce the start configuration
    assert space.config(space.start_values(), name=start.name) == start


def test_trial_values_keep_the_spread_and_stay_valid():
    start = load_config("high")
    space = default_space(start)
    extreme = space.config({p.name: p.high for p in space.parameters})
    assert extreme.stain.hue_deg.kind == "uniform"  # a range stays a range, shifted
    width = start.stain.hue_deg.values[1] - start.stain.hue_deg.values[0]
    assert extreme.stain.hue_deg.values[1] - extreme.stain.hue_deg.values[0] == pytest.approx(width)
    space.config({p.name: p.low for p in space.parameters})  # validates


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("stain.hue_dg: [250, 290]\n", "space.yaml: stain.hue_dg: unknown parameter (did you mean stain.hue_deg?)"),
        ("stain.hue_deg: [250, 400]\n", "space.yaml: stain.hue_deg: 400 is out of range: valid range is [0, 360] deg"),
        ("post.noise: [0, 2]\n", "space.yaml: post.noise: 2 is out of range: valid range is [0, 1]"),
        ("stain.hue_deg: [red, 290]\n", "space.yaml: stain.hue_deg: expected a number, a [low, high] range or a "
                                        "mapping like {loguniform: [low, high]}, got 'red'"),
        ("post.noise: [a, 1]\n", "space.yaml: post.noise: wrong type (Input should be a valid number), got 'a'"),
        ("stain.hue_deg: [290, 250]\n", "space.yaml: stain.hue_deg: the range needs low < high, got [290, 250]"),
        ("background.kind: [0, 1]\n", "space.yaml: background.kind: a category cannot be searched"),
        ("plate.format: [6, 24]\n", "space.yaml: plate.format: takes one of 6, 12, 24, 96 and cannot be searched"),
        ("stain.hue_deg: 250\n", "space.yaml: stain.hue_deg: expected [low, high], {range: [low, high], log: true}"),
        ("[1, 2]\n", "space.yaml: expected a mapping of parameter names to ranges"),
    ],
)
def test_bad_space_is_refused_with_one_line(tmp_path, text, message):
    path = tmp_path / "space.yaml"
    path.write_text(text)
    with pytest.raises(ParameterError) as caught:
        load_space(path, load_config("low"))
    assert str(caught.value).startswith(message.replace("space.yaml", str(path)))
    assert "\n" not in str(caught.value)


def test_space_file_ranges(tmp_path):
    path = tmp_path / "space.yaml"
    path.write_text("stain.hue_deg: [250, 290]\nplaques.radius_mm: {range: [0.3, 1.5], log: true}\npost.noise: auto\n")
    space = load_space(path, load_config("low"))
    assert space.names == ["stain.hue_deg", "plaques.radius_mm", "post.noise"]
    assert space.parameters[1].log and (space.parameters[2].low, space.parameters[2].high) == (0.0, 0.25)


def test_space_file_over_the_default_space(tmp_path):
    path = tmp_path / "space.yaml"
    path.write_text("all: auto\npost.noise: [0, 1]\nplate.tint: [0, 0.1]\n")
    start = load_config("low")
    space = load_space(path, start)
    default = default_space(start)
    assert space.names == default.names + ["plate.tint"]
    noise = space.parameters[space.names.index("post.noise")]
    assert (noise.low, noise.high) == (0.0, 1.0)


def test_fixed_takes_a_parameter_out_of_the_default_space(tmp_path):
    path = tmp_path / "space.yaml"
    path.write_text("all: auto\nplaques.radius_mm: fixed\nplaques.max_coverage: fixed\n")
    start = load_config("low")
    space = load_space(path, start)
    assert space.names == [n for n in default_space(start).names if n not in ("plaques.radius_mm", "plaques.max_coverage")]
    path.write_text("all: auto\nplaques.radius: fixed\n")
    with pytest.raises(ParameterError, match="plaques.radius"):
        load_space(path, start)


def test_split_is_by_plate_seeded_and_balanced(tmp_path):
    for group, n in (("A", 6), ("B", 4)):
        for i in range(n):
            (tmp_path / f"{group}_plate{i}.png").write_bytes(b"")
    first, again, other = (split_reference(tmp_path, seed) for seed in (1, 1, 2))
    assert first == again and first != other
    assert not set(first.fit) & set(first.check) and len(first.fit) + len(first.check) == 10
    assert sum(p.name.startswith("A") for p in first.check) == 3 and sum(p.name.startswith("B") for p in first.check) == 2


# ------------------------------------------------------------------------------------------------ tiny runs


def test_tiny_run_completes(run_of_four):
    out = run_of_four.out
    for name in ("best.yaml", "trials.csv", "trials.json", "report.json", "report.md", "contact_sheet.png",
                 "history.png", "importances.png", "study.db", "split.json"):
        assert (out / name).is_file(), name
    rows = _trials(out)
    assert [row["number"] for row in rows] == [0, 1, 2, 3] and rows[0]["start"]
    assert all(row["state"] == "complete" and row["fd_images"] > 0 and row["fd_wells"] > 0 for row in rows)
    report = run_of_four.report
    for part in ("fit", "check"):
        assert set(report["evaluation"][part]) == {"start", "best"}
        assert {"objective", "fd_images", "fd_wells", "dnf", "entropy_gap"} <= set(report["evaluation"][part]["best"])
    assert not set(report["split"]["fit"]) & set(report["split"]["check"])
    best = load_config(path=out / "best.yaml")  # usable with --config
    assert best.model_dump(exclude={"name"}) != load_config("low").model_dump(exclude={"name"}) or report["best_trial"] == 0


def test_deterministic_and_resumed_without_repeating(run_of_four, reference, tmp_path, one_torch_thread):
    out = tmp_path / "resumed"
    optimise(reference, out, preset="low", trials=2, **TINY)
    first_two = _trials(out)
    import optuna

    before = {t.number: t.datetime_start for t in optuna.load_study(study_name="platesynth-optimise",
                                                                     storage=f"sqlite:///{out / 'study.db'}").trials}
    optimise(reference, out, preset="low", trials=4, **TINY)
    after = optuna.load_study(study_name="platesynth-optimise", storage=f"sqlite:///{out / 'study.db'}").trials
    assert len(after) == 4 and all(after[n].datetime_start == before[n] for n in (0, 1))  # not run again
    assert _trials(out)[:2] == first_two
    assert _trials(out) == _trials(run_of_four.out)  # interrupted or not, the same trials for the same seed


def test_trials_on_a_dask_cluster_equal_those_in_one_process(run_of_four, reference, tmp_path):
    distributed = pytest.importorskip("distributed", reason="the Dask executor needs the 'dask' extra")
    from platesynth.data.executor import DaskExecutor

    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None,
                                  scheduler_kwargs={"dashboard_address": ":0"}) as cluster:
        result = optimise(reference, tmp_path / "dask", preset="low", trials=4,
                          executor=DaskExecutor(scheduler=cluster.scheduler_address), **TINY)
    # the same trials: parameters and states exactly; the metrics up to the order of BLAS's sums, which depends on
    # its thread count (one thread in a Dask worker: its nanny sets OMP_NUM_THREADS=1 by default)
    assert _close(_trials(result.out), _trials(run_of_four.out))
    assert _close(result.report["evaluation"], run_of_four.report["evaluation"])


def _close(a, b, rel=1e-7):
    """Equal, floats up to ``rel`` (recursively through lists and dicts)."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_close(a[k], b[k], rel) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_close(x, y, rel) for x, y in zip(a, b))
    if isinstance(a, float) and isinstance(b, float):
        return a == pytest.approx(b, rel=rel, nan_ok=True)
    return a == b


def test_other_settings_in_the_same_folder_are_refused(run_of_four, reference):
    with pytest.raises(OutputError, match="holds an optimisation with other settings \\(eval_count\\)"):
        optimise(reference, run_of_four.out, preset="low", trials=4, **{**TINY, "eval_count": 4})


def test_failed_trials_are_recorded_not_fatal(reference, weights, tmp_path, monkeypatch, one_torch_thread):
    from platesynth.optimise import objective

    real = objective.compare

    def sometimes_nan(measured, ref):  # the second trial's fd_wells is NaN
        terms = real(measured, ref)
        if sometimes_nan.calls == 1:
            terms["fd_wells"] = float("nan")
        sometimes_nan.calls += 1
        return terms

    sometimes_nan.calls = 0
    monkeypatch.setattr(objective, "compare", sometimes_nan)
    result = optimise(reference, tmp_path / "nan", preset="low", trials=3, **TINY)
    states = [row["state"] for row in _trials(tmp_path / "nan")]
    assert states == ["complete", "fail", "complete"]
    assert "fd_wells not finite" in _trials(tmp_path / "nan")[1]["error"]
    assert result.report["n_failed"] == 1
    # a trial left running by a run that stopped is recorded as failed (interrupted) by the next run
    import optuna

    optuna.load_study(study_name="platesynth-optimise", storage=f"sqlite:///{tmp_path / 'nan' / 'study.db'}").ask()
    optimise(reference, tmp_path / "nan", preset="low", trials=4, **TINY)
    rows = _trials(tmp_path / "nan")
    assert [row["state"] for row in rows] == ["complete", "fail", "complete", "fail"]
    assert rows[3]["error"].startswith("interrupted")


def test_command_line_refuses_a_bad_space_before_writing(reference, weights, tmp_path):
    from typer.testing import CliRunner

    from platesynth.cli import app

    space = tmp_path / "space.yaml"
    space.write_text("stain.hue_deg: [250, 400]\n")
    out = tmp_path / "never"
    args = ["optimise", "--reference", reference, "--out", out, "--trials", 2, "--preset", "low", "--space", space]
    done = CliRunner().invoke(app, [str(a) for a in args])
    assert done.exit_code == 1 and done.stdout == ""
    assert done.stderr.strip().splitlines() == [
        f"error: {space}: stain.hue_deg: 400 is out of range: valid range is [0, 360] deg"
    ]
    assert not out.exists()


def test_multi_objective_keeps_a_pareto_front(reference, weights, tmp_path, one_torch_thread):
    result = optimise(reference, tmp_path / "multi", preset="low", trials=2, multi_objective=True, **TINY)
    assert result.report["objectives"] == ["fd_images", "fd_wells", "dnf", "entropy_gap"]
    assert result.report["best_trial"] in result.report["pareto_trials"]
    assert (tmp_path / "multi" / "pareto.csv").is_file() and (tmp_path / "multi" / "pareto.png").is_file()


# ------------------------------------------------------------------------------------------ the plaque-size term


@pytest.fixture(scope="module")
def shipped_model():
    from pathlib import Path

    model = Path(__file__).resolve().parents[1] / "models" / "plaque12"
    if not (model / "weights.pt").is_file():
        pytest.skip(f"{model}: the shipped model is missing")
    return model


def test_plaque_sizes_are_measured_alike_in_renders_and_photos(reference, shipped_model, one_torch_thread):
    import numpy as np

    from platesynth.data.batch import build_manifest, render_item
    from platesynth.metrics.wells import plaque_area_distance, plaque_measurements
    from platesynth.optimise.objective import MeasuredSet, Reference, compare, plaque_area_fractions
    from platesynth.segment.model import load_model
    from platesynth.segment.predict import predict_image

    manifest = build_manifest(preset="high", seed=6, count=2, size=(608, 472))  # plaques in both
    images = [render_item(manifest, index)[0].image for index in range(2)]
    fractions = plaque_area_fractions(images, str(shipped_model))
    found = predict_image(load_model(shipped_model), images[1])
    second = plaque_measurements(images[1], found.wells, found.plaques)["area_fraction"]
    assert fractions.size > second.size > 10  # both images' plaques, in order
    np.testing.assert_array_equal(fractions[-second.size:], second)
    assert np.all((fractions > 0) & (fractions < 0.5))

    def measured(values):
        return MeasuredSet(np.eye(3), np.eye(3), 1.0, (np.zeros((4, 4), np.uint8),) * 2,
                           plaque_area_fractions=values)

    photos = Reference("fit", ("a", "b"), measured(fractions / 2), 2, 0.0)
    terms = compare(measured(fractions), photos)
    assert terms["plaque_sizes"] == pytest.approx(np.log10(2)) == pytest.approx(plaque_area_distance(fractions, fractions / 2))
    assert terms["plaques_found"] == 0.0  # as many per image
    fewer_found = Reference("fit", ("a", "b", "c", "d"), measured(fractions / 2), 2, 0.0)  # in twice as many photos
    assert compare(measured(fractions), fewer_found)["plaques_found"] == pytest.approx(np.log10(2))
    assert not {"plaque_sizes", "plaques_found"} & set(compare(measured(None), photos))  # no plaque model, no terms


def test_a_run_with_a_plaque_model_reports_plaque_sizes(reference, weights, shipped_model, tmp_path, monkeypatch,
                                                        one_torch_thread):
    from platesynth.optimise import objective

    real = objective.plaque_area_fractions

    def none_found_in_the_second_trial(images, model_dir):
        # measured in this order: the photos' two halves, trial 0, trial 1, then the best configuration's evaluation
        none_found_in_the_second_trial.calls += 1
        found = real(images, model_dir)
        return found[:0] if none_found_in_the_second_trial.calls == 4 else found

    none_found_in_the_second_trial.calls = 0
    monkeypatch.setattr(objective, "plaque_area_fractions", none_found_in_the_second_trial)
    result = optimise(reference, tmp_path / "plaques", preset="high", trials=2, plaque_model=shipped_model,
                      multi_objective=True, **{**TINY, "size": (304, 236)})
    start, other = _trials(tmp_path / "plaques")
    assert start["state"] == "complete" and 0 < start["plaque_sizes"] < 1 and 0 <= start["plaques_found"] < 2
    # a trial whose renders hold no plaque the model finds is recorded as failed, not fatal
    assert other["state"] == "fail" and "no plaques in one of the sets" in other["error"]
    assert {"plaque_sizes", "plaques_found"} <= set(result.report["objectives"])
    for part in ("fit", "check"):
        assert {"plaque_sizes", "plaques_found"} <= set(result.report["evaluation"][part]["best"])


def test_a_missing_plaque_model_is_refused_before_writing(reference, weights, tmp_path):
    from platesynth.errors import DatasetError

    with pytest.raises(DatasetError):
        optimise(reference, tmp_path / "never", preset="low", trials=2, plaque_model=tmp_path / "no-model", **TINY)
    assert not (tmp_path / "never").exists()
