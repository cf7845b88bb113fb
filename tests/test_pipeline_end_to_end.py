"""The whole default workflow on the shared tiny run: curation, dataset, learning and reports wired end to
end, checked against the twin's truth where there is one."""

import json

import cv2
import numpy as np
import pandas as pd
import pytest
from conftest import TINY_CONFIG
from workflow_util import snakemake

from pingpong.frames import N_INPUT


def test_curation_keeps_good_returns_and_names_every_fault(tiny_run):
    segments = pd.read_parquet(tiny_run / "processed/segments.parquet")
    assert len(segments) > 0 and segments["decision"].notna().all()
    kept = segments[segments["decision"] == "kept"]
    # every kept hit is a true good return of the same session: found through the whole perception
    # chain, nearly all within one frame (test_segments holds the event detector itself to 99 %)
    gaps = []
    for session, rows in kept.groupby("session"):
        shots = pd.read_parquet(tiny_run / f"raw/twin_truth/{session}/shots.parquet")
        good = shots.loc[shots["outcome"] == "ok", "t_hit_ns"].to_numpy()
        gaps.append(np.abs(rows["t_hit_ns"].to_numpy()[:, None] - good[None]).min(axis=1))
    gaps = np.concatenate(gaps) / 10_000_000  # frames
    assert len(gaps) >= 10 and gaps.max() < 3 and np.mean(gaps <= 1) >= 0.9
    table = pd.read_csv(tiny_run / "reports/tables/curation.csv")
    assert table["candidates"].sum() == len(segments)


def test_dataset_holds_mirrored_39_value_sequences_split_by_rally(tiny_run):
    dataset = pd.read_parquet(tiny_run / "processed/dataset.parquet")
    X = np.stack(dataset["x"].to_numpy()).reshape(len(dataset), -1, N_INPUT)
    assert X.shape[1] == 40 and np.isfinite(X).all()
    assert (X[:, -1, 37] > 0).all()  # the ball at the hit is on the hitter's (+y) side after mirroring
    parts = dataset.groupby(["session", "rally"])["split"].nunique()
    assert (parts == 1).all()


def test_learning_outputs_predictions_for_every_held_out_hit_and_frame(tiny_run):
    dataset = pd.read_parquet(tiny_run / "processed/dataset.parquet")
    pred = pd.read_parquet(tiny_run / "processed/predictions.parquet")
    held_out = (dataset["split"] != "train").sum()
    assert (pred[pred["model"] == "ball_only"].shape[0]) == 31 * held_out
    assert (pred[pred["model"] == "final_zero_phase"].shape[0]) == 31 * held_out  # the other inputs' model
    assert set(pred["frames_before_hit"]) == set(range(0, 31))  # t = -30 .. 0
    final = pred[pred["model"] == "final"]
    assert len(final) == 31 * len(dataset)  # held-out by the final model, training hits out of fold
    selection = json.loads((tiny_run / "processed/models/selection.json").read_text())
    assert selection["config"]["cell"] == "gru"
    table = pd.read_csv(tiny_run / "reports/tables/strike_error.csv")
    assert set(table["model"]) == {"final", "final_zero_phase", "ball_only", "mean"}
    assert set(table["frames_before_hit"]) == {10, 1, 0}
    assert (tiny_run / "reports/figures/strike_error.png").stat().st_size > 1000


def test_uncertainty_tables_for_every_estimator_held_out_hit_and_frame(tiny_run):
    from pingpong.uncertainty.names import ESTIMATORS

    dataset = pd.read_parquet(tiny_run / "processed/dataset.parquet")
    held_out = (dataset["split"] != "train").sum()
    assert len(list((tiny_run / "processed/models/final").glob("seed*.safetensors"))) == 2
    for name in ESTIMATORS:
        table = pd.read_parquet(tiny_run / f"processed/uncertainty/{name}.parquet")
        assert len(table) == 31 * held_out and set(table["split"]) <= {"calibration", "test"}, name
        assert (table["uncertainty"] >= 0).all(), name  # +inf where too few calibration hits
        interval = table["lower"].notna()
        assert (table.loc[interval, "lower"] <= table.loc[interval, "upper"]).all(), name
    assert (tiny_run / "processed/uncertainty/quantile_heads.safetensors").is_file()
    report = pd.read_csv(tiny_run / "reports/tables/uncertainty.csv")
    assert list(report["estimator"]) == [*ESTIMATORS, "oracle"]  # the twin's oracle: the ceiling row
    oracle = report.set_index("estimator").loc["oracle"]
    assert oracle["spearman_oracle_within_frame"] == pytest.approx(1.0)  # its std against itself
    verdict = pd.read_csv(tiny_run / "reports/tables/uncertainty_verdict.csv")
    assert list(verdict["estimator"]) == list(ESTIMATORS) and (verdict["n_oracle_hits"] > 0).all()
    bands = pd.read_csv(tiny_run / "reports/tables/uncertainty_path_band.csv").set_index("band")
    assert set(bands.index) == {"simultaneous", "pointwise"}
    simultaneous = bands.loc["simultaneous"]
    assert simultaneous["whole_path_coverage"] <= simultaneous["strike_point_coverage"]
    for figure in ("error_vs_uncertainty", "error_vs_frames", "sparsification", "spearman_oracle_by_frame",
                   "coverage_by_width"):
        assert (tiny_run / f"reports/figures/uncertainty_{figure}.png").stat().st_size > 1000


def test_robot_simulates_every_test_hit_per_controller_within_the_limits(tiny_run):
    dataset = pd.read_parquet(tiny_run / "processed/dataset.parquet")
    test_hits = dataset.loc[dataset["split"] == "test", ["session", "rally", "hit"]]
    table = pd.read_csv(tiny_run / "reports/tables/robot.csv")
    controllers = ["servo", "anticipatory", "uncertainty_aware", "confidence_scaled",
                   "confidence_scaled_oracle"]
    assert list(table["controller"].unique()) == controllers
    for controller in controllers:
        sim = pd.read_parquet(tiny_run / f"processed/sim/{controller}.parquet")
        assert len(sim) == len(test_hits)
        simulated = set(map(tuple, sim[["session", "rally", "hit"]].to_numpy()))
        assert simulated == set(map(tuple, test_hits.to_numpy()))
        assert sim["limits_ok"].all()  # no limit exceeded at any step of any test episode
        assert (sim["hit_ball"] == (sim["end_distance_m"] <= 0.08)).all()
        choice = json.loads((tiny_run / f"processed/sim/{controller}.json").read_text())
        assert choice["controller"] == controller
        all_row = table[(table["controller"] == controller) & (table["region"] == "all")].iloc[0]
        assert all_row["total"] == len(sim) and all_row["hits"] == sim["hit_ball"].sum()
    sweep = json.loads((tiny_run / "processed/sim/uncertainty_aware.json").read_text())["sweep"]
    assert len(sweep) == 36  # the default 6 x 6 alpha grid, the paper's 0.6 in it
    assert {(c["alpha1"], c["alpha2"]) for c in sweep} >= {(0.6, 1.0)}
    limits = pd.read_csv(tiny_run / "reports/tables/robot_limits.csv")
    arm = limits[limits["joint"].str.startswith("iiwa")]
    assert np.allclose(arm["acceleration_used"], arm["acceleration_table6"])  # the paper's Table 6
    assert (arm["acceleration_drake"] < arm["derived_coupled_min"]).all()  # Drake's: reachable everywhere


def test_robot_ablation_covers_every_combination_within_the_limits(tiny_run):
    dataset = pd.read_parquet(tiny_run / "processed/dataset.parquet")
    n_test = (dataset["split"] == "test").sum()
    table = pd.read_csv(tiny_run / "reports/tables/robot_ablation.csv")
    combos = table[table["controller"].isin(["servo", "anticipatory"]) & (table["servo_fit"] == "model")]
    assert len(combos.drop_duplicates(["accelerations", "timing", "inputs", "controller"])) == 16
    assert (table["total"] == n_test).all() and (table["limit_breaches"] == 0).all()
    assert (table["controller"] == "perfect").sum() == 1 and (table["servo_fit"] == "paper").sum() == 1
    configured = table.loc[table["changed"] == "none", "controller"].tolist()
    assert configured == ["servo", "anticipatory", "perfect"]
    servo = pd.read_csv(tiny_run / "reports/tables/servo_accuracy.csv")
    on_test = servo[servo["flights"] == "test"]
    assert set(on_test["fit"]) == {"paper", "model", "model_twin_ball"}
    assert set(on_test["frames_after_hit"]) == {10, 15, 20} and set(servo["flights"]) == {"test", "ball_gun"}
    # the servo's ball is fitted on half the real flights, measured on the other half
    assert (servo.loc[servo["flights"] == "ball_gun", "n_flights"] == 53).all()


def test_html_report_shows_every_stage_table_and_figure(tiny_run):
    snakemake(tiny_run, "--report", "reports/report.html", configfile=TINY_CONFIG)
    report = (tiny_run / "reports/report.html").read_text()
    for table in ("twin_vs_real", "perception_accuracy", "curation", "cv_results", "strike_error",
                  "uncertainty", "robot", "robot_limits"):
        page = next((tiny_run / "reports/pages").glob(f"*/{table}.html"))
        assert f"{table}.html" in report
        title = page.read_text().split("<h1>")[1].split("</h1>")[0]
        assert title and "<table" in page.read_text()
    for figure in ("strike_error", "uncertainty_sparsification", "robot_scene"):
        assert f"{figure}.png" in report


def test_robot_scenes_of_the_first_test_hits_open_as_foxglove_mcap(tiny_run):
    from mcap.reader import make_reader

    dataset = pd.read_parquet(tiny_run / "processed/dataset.parquet")
    first = dataset[dataset["split"] == "test"].head(2)  # robot.scene_hits defaults to 2
    for controller in ("servo", "anticipatory", "uncertainty_aware", "confidence_scaled"):
        sim = pd.read_parquet(tiny_run / f"processed/sim/{controller}.parquet")
        for k, hit in enumerate(first.itertuples(index=False)):
            with open(tiny_run / f"processed/sim/scenes/{controller}_test{k}.mcap", "rb") as f:
                reader = make_reader(f)
                summary = reader.get_summary()
                schemas = {summary.schemas[c.schema_id].name for c in summary.channels.values()}
                episode = next(dict(m.metadata) for m in reader.iter_metadata() if m.name == "episode")
            assert schemas == {"foxglove.SceneUpdate", "foxglove.FrameTransforms"}
            assert summary.statistics.message_count > 0
            assert (episode["session"], int(episode["rally"]), int(episode["hit"])) == (
                hit.session, hit.rally, hit.hit)
            row = sim[(sim["session"] == hit.session) & (sim["rally"] == hit.rally) & (sim["hit"] == hit.hit)]
            # the scene replays the episode of the simulation table (the rule checks the end distance too)
            assert episode["hit_ball"] == str(bool(row["hit_ball"].iloc[0]))
    image = cv2.imread(str(tiny_run / "reports/figures/robot_scene.png"))
    assert image is not None and image.std() > 20


def test_twin_run_reports_curation_against_the_truth(tiny_run):
    table = pd.read_csv(tiny_run / "reports/tables/curation_accuracy.csv")
    assert list(table.columns) == ["quantity", "value", "unit", "threshold", "must_be", "ok"]
    assert set(table["quantity"]) == {
        "true hits found within a frame", "spurious detected hits", "true bounces found within a frame",
        "spurious detected bounces", "candidates that are true hits",
        "decisions agreeing with the twin's outcome",
        "kept candidates that are true ok returns", "true faults rejected as that fault",
        "unfiltered 3D ball error in flight (median)", "filtered 3D ball error in flight (median)",
        "label strike point vs measured crossing (median)", "measured strike point vs truth (median)"}
    assert table["value"].notna().all()
