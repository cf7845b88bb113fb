"""The strike-oracle report on synthetic tables with known answers: a model at the oracle's mean with the
truth drawn from the oracle's Gaussian leaves only irreducible error and is covered 90 %; an oracle std
that orders the errors ranks them perfectly; far hitters' oracles are mirrored like their hits; hits
match their shot within one frame only; the causes table pools every shot by stroke, deception and
pressure tercile; the stage writes both tables and the figure."""

import numpy as np
import pandas as pd
import pytest
from hypothesis import given
from hypothesis import strategies as st

from pingpong.common.artifacts import Provenance, write_table
from pingpong.common.script import Named, StageContext
from pingpong.curation.schemas import DATASET
from pingpong.frames import FRAME_NS
from pingpong.learning.schemas import PREDICTIONS
from pingpong.reports import uncertainty_oracle as ro
from pingpong.stages import report_uncertainty_oracle as stage
from pingpong.twin import truth

Z95 = 1.6448536269514722  # standard normal 95 % quantile
FRAMES = np.arange(31)


def _gaussian_hits(rng, n, frames=(10, 0), bias=0.0):
    """Joined rows (as join_test_hits gives) where the label is drawn from the oracle's own Gaussian and
    the model predicts the oracle's mean (+ bias)."""
    k = len(frames)
    mean = rng.uniform(-0.6, 0.6, n * k)
    std = 0.08 * rng.lognormal(0, 0.5, n * k)
    label = mean + std * rng.standard_normal(n * k)
    return pd.DataFrame({"frames_before_hit": np.tile(frames, n), "oracle_mean_x": mean, "oracle_std_x": std,
                         "oracle_q05_x": mean - Z95 * std, "oracle_q95_x": mean + Z95 * std,
                         "strike_x": label, "abs_error": np.abs(mean + bias - label)})


def test_a_model_at_the_oracle_mean_has_only_irreducible_error_and_90_percent_coverage():
    n = 20_000  # share's relative standard error sqrt((3 e^(4 s^2) - 1) / n) = 0.019 (s = 0.5): 0.08 is > 4
    table = ro.by_frame_table(_gaussian_hits(np.random.default_rng(1), n))
    assert list(table["frames_before_hit"]) == [10, 0] and (table["n_hits"] == n).all()
    assert np.allclose(table["irreducible_share"], 1, atol=0.08), table
    assert np.allclose(table["misfit_share"], 1 - table["irreducible_share"])
    assert np.allclose(table["coverage_q05_q95"], 0.9, atol=0.01), table  # binomial s.e. 0.002
    assert (table["spearman"] > 0.3).all()  # wider oracles do see larger errors on average


def test_a_biased_model_leaves_a_misfit_share_of_bias_squared():
    bias = 0.1  # m, against mean oracle variance 0.0064 * e^0.5 = 0.0106 m^2
    table = ro.by_frame_table(_gaussian_hits(np.random.default_rng(2), 20_000, bias=bias))
    variance = 0.08**2 * np.exp(2 * 0.5**2)
    assert np.allclose(table["irreducible_share"], variance / (variance + bias**2), atol=0.03), table
    assert np.allclose(table["model_mse_cm2"], 1e4 * (variance + bias**2), rtol=0.05)
    assert (table["misfit_share"] > 0.4).all()


def test_an_oracle_std_that_orders_the_errors_ranks_them_perfectly():
    rng = np.random.default_rng(3)
    hits = _gaussian_hits(rng, 300)
    ordered = ro.by_frame_table(hits.assign(oracle_std_x=0.01 + 2 * hits["abs_error"] ** 2))
    assert np.allclose(ordered["spearman"], 1) and np.allclose(ordered["ause"], 0, atol=1e-12)
    reversed_ = ro.by_frame_table(hits.assign(oracle_std_x=1 / (0.01 + hits["abs_error"])))
    assert np.allclose(reversed_["spearman"], -1) and (reversed_["ause"] > 0.3).all()
    cv = ordered.set_index("frames_before_hit")["oracle_std_cv"]
    std = 0.01 + 2 * hits["abs_error"] ** 2
    assert cv[10] == pytest.approx(std[hits["frames_before_hit"] == 10].std(ddof=0)
                                   / std[hits["frames_before_hit"] == 10].mean())


@given(mean=st.floats(-1, 1), half=st.floats(0, 0.5), skew=st.floats(-0.2, 0.2), x=st.floats(-1.5, 1.5),
       far=st.booleans())
def test_mirroring_keeps_the_interval_ordered_and_covering_the_mirrored_point(mean, half, skew, x, far):
    row = pd.DataFrame({"oracle_mean_x": [mean], "oracle_std_x": [half / 2],
                        "oracle_q05_x": [mean - half + skew], "oracle_q95_x": [mean + half + skew]})
    m = ro.mirror_oracle(row, [far]).iloc[0]
    sign = -1 if far else 1
    assert m["oracle_mean_x"] == sign * mean and m["oracle_std_x"] == half / 2
    assert m["oracle_q05_x"] <= m["oracle_q95_x"]
    inside = row["oracle_q05_x"].iloc[0] <= x <= row["oracle_q95_x"].iloc[0]
    assert (m["oracle_q05_x"] <= sign * x <= m["oracle_q95_x"]) == inside
    assert ro.mirror_oracle(ro.mirror_oracle(row, [far]), [far]).equals(row)


def _oracle(n_shots, t0_ns=1_000_000_000, std=lambda shot, frame: 0.02 + 0.01 * frame):
    """One session's oracle: shot k at t0 + k * 1.5 s, rally k // 3; mean 0.1 * (k + 1) (table frame),
    quantiles asymmetric (q05 = mean - 2 std, q95 = mean + std) so that a missing swap shows."""
    rows = []
    for k in range(n_shots):
        for f in FRAMES:
            s = std(k, f)
            rows.append({"rally": k // 3, "shot": k % 3, "t_hit_ns": t0_ns + k * 1_500_000_000,
                         "frames_before_hit": int(f), "oracle_mean_x": 0.1 * (k + 1), "oracle_std_x": s,
                         "oracle_q05_x": 0.1 * (k + 1) - 2 * s, "oracle_q95_x": 0.1 * (k + 1) + s})
    return pd.DataFrame(rows)


def _hits(oracle, session, offsets_ns, hitters):
    """Dataset and final-model predictions for one test hit per oracle shot, t_hit_ns off by offsets_ns;
    curation's rallies are numbered unlike the twin's. The label is the oracle mean, mirrored."""
    shots = oracle.drop_duplicates(["rally", "shot"]).reset_index(drop=True)
    sign = np.where(np.asarray(hitters) == "far", -1.0, 1.0)
    dataset = pd.DataFrame({"session": session, "rally": 100 + np.arange(len(shots)), "hit": 0,
                            "hitter": hitters, "t_hit_ns": shots["t_hit_ns"] + np.asarray(offsets_ns),
                            "split": "test", "strike_x": sign * shots["oracle_mean_x"]})
    pred = dataset.loc[dataset.index.repeat(len(FRAMES))].reset_index(drop=True)
    pred["frames_before_hit"] = np.tile(FRAMES, len(dataset))
    pred["model"], pred["strike_x_pred"] = "final", pred["strike_x"] + 0.01
    pred["abs_error"] = 0.01
    other = pred.assign(model="ball_only", strike_x_pred=0.0)  # must not be taken for the final model
    return dataset, pd.concat([pred, other], ignore_index=True)


def test_far_hitters_oracles_are_mirrored_and_hits_match_their_shot_within_a_frame():
    oracle = _oracle(4)
    dataset, pred = _hits(oracle, "s00", [0, FRAME_NS, -FRAME_NS // 2, 3 * FRAME_NS // 2],
                          ["near", "far", "far", "near"])
    joined = ro.join_test_hits(dataset, pred, {"s00": oracle})
    assert sorted(joined["rally"].unique()) == [100, 101, 102]  # the last is 1.5 frames off
    assert len(joined) == 3 * len(FRAMES) and (joined["strike_x_pred"] == joined["strike_x"] + 0.01).all()
    # every hit's label is its shot's mean, mirrored: the oracle, mirrored alike, agrees
    assert np.allclose(joined["oracle_mean_x"], joined["strike_x"])
    far = joined[joined["hitter"] == "far"]
    assert (far["oracle_mean_x"] < 0).all()  # table-frame means are all positive
    assert np.allclose(far["oracle_q05_x"], far["oracle_mean_x"] - far["oracle_std_x"])  # q95 flipped
    assert np.allclose(far["oracle_q95_x"], far["oracle_mean_x"] + 2 * far["oracle_std_x"])
    near = joined[joined["hitter"] == "near"]
    assert np.allclose(near["oracle_q05_x"], near["oracle_mean_x"] - 2 * near["oracle_std_x"])
    first = joined.drop_duplicates("rally")
    assert list(zip(first["twin_rally"], first["twin_shot"], strict=True)) == [(0, 0), (0, 1), (0, 2)]
    assert (ro.by_frame_table(joined)["coverage_q05_q95"] == 1).all()


def test_the_oracle_as_an_uncertainty_table_covers_every_held_out_row():
    """The oracle-driven controller's table: calibration and test rows alike, the oracle's std (mirrored
    interval) where a shot matched, an infinite uncertainty where none did."""
    oracle = _oracle(3)
    dataset, pred = _hits(oracle, "s00", [0, 0, 3 * FRAME_NS], ["near", "far", "near"])
    dataset["split"] = ["calibration", "test", "test"]
    pred["split"] = pred["rally"].map(dict(zip(dataset["rally"], dataset["split"], strict=True)))
    table = ro.oracle_uncertainty(dataset, pred, {"s00": oracle})
    assert len(table) == 3 * len(FRAMES) and set(table["split"]) == {"calibration", "test"}
    matched = table[table["rally"] < 102]
    assert np.allclose(matched["uncertainty"], matched["oracle_std_x"]) and (matched["std"] > 0).all()
    assert (matched["lower"] < matched["upper"]).all()
    assert np.isinf(table.loc[table["rally"] == 102, "uncertainty"]).all()  # 3 frames off: no shot


@given(offset=st.integers(-3 * FRAME_NS, 3 * FRAME_NS))
def test_a_hit_matches_its_shot_exactly_when_within_one_frame(offset):
    oracle = _oracle(2)
    dataset, pred = _hits(oracle, "s01", [offset, 0], ["far", "near"])
    joined = ro.join_test_hits(dataset, pred, {"s01": oracle})
    assert (100 in set(joined["rally"])) == (abs(offset) <= FRAME_NS)
    assert 101 in set(joined["rally"])


def _with_causes(n_shots=30, session="s00"):
    """Oracle and shots of one session: stroke by shot (the std grows with frames, stroke 'smash' twice
    as wide), deception alternating, pressure k / (n - 1)."""
    strokes = np.array(["drive", "smash", "push"])[np.arange(n_shots) % 3]
    scale = np.where(strokes == "smash", 2.0, 1.0)
    oracle = _oracle(n_shots, std=lambda k, f: scale[k] * (0.01 + 0.002 * f))
    shots = oracle.drop_duplicates(["rally", "shot"])[["rally", "shot", "t_hit_ns"]].reset_index(drop=True)
    shots["stroke"] = strokes
    shots["deception"] = np.array(["disguise", "telegraph"])[np.arange(n_shots) % 2]
    shots["pressure"] = np.arange(n_shots) / (n_shots - 1)
    return oracle, shots


def test_the_causes_table_pools_every_shot_by_cause():
    oracle, shots = _with_causes()
    rows = ro.oracle_with_causes(oracle, shots).assign(session="s00")
    table = ro.causes_table(rows).set_index(["cause", "value"])
    assert list(table.index.get_level_values("value")) == [
        "all", "drive", "push", "smash", "telegraph", "disguise", "low", "mid", "high"]  # ORDER
    assert table.loc[("all", "all"), "n_shots"] == 30 and table.loc[("stroke", "smash"), "n_shots"] == 10
    assert table.loc[("stroke", "drive"), "oracle_std_cm_f20"] == pytest.approx(100 * (0.01 + 0.04))
    assert table.loc[("stroke", "smash"), "oracle_std_cm_f0"] == pytest.approx(100 * 0.02)
    assert table.loc[("deception", "disguise"), "oracle_std_cm_f10"] == pytest.approx(100 * 0.03 * 4 / 3)
    pressure = table.loc["pressure"]
    assert (pressure["n_shots"] == 10).all() and pressure.loc["low", "pressure_from"] == 0
    assert pressure.loc["high", "pressure_to"] == 1
    assert pressure.loc["low", "pressure_to"] == pytest.approx(1 / 3)
    at10 = 0.03 * np.where(shots["stroke"] == "smash", 2.0, 1.0)
    assert table.loc[("all", "all"), "oracle_std_cv_f10"] == pytest.approx(at10.std() / at10.mean())
    assert np.isnan(table.loc[("stroke", "drive"), "pressure_from"])
    long = ro.std_by_cause(rows)
    assert len(long) == 9 * len(FRAMES)
    with pytest.raises(ValueError, match="no shot"):
        ro.oracle_with_causes(oracle.assign(t_hit_ns=oracle["t_hit_ns"] + 1), shots)


def test_the_stage_writes_both_tables_and_the_figure(tmp_path):
    rng = np.random.default_rng(4)
    prov = Provenance.of("test")
    inputs = Named(shots=[], oracle=[])
    datasets, preds = [], []
    for session in ["s00", "s01"]:
        oracle, shots = _with_causes(12)
        oracle["oracle_std_x"] *= rng.uniform(0.5, 1.5, len(oracle))
        hitters = np.where(np.arange(12) % 2, "far", "near")
        dataset, pred = _hits(oracle, session, rng.integers(-FRAME_NS, FRAME_NS, 12), hitters)
        datasets.append(dataset.iloc[:11])  # the last shot has no kept hit
        preds.append(pred[pred["rally"] != dataset["rally"].iloc[11]])
        oracle = oracle.assign(oracle_n=200)
        for name, table, schema in (("shots", shots, truth.SHOTS), ("oracle", oracle, truth.ORACLE)):
            path = tmp_path / f"{session}_{name}.parquet"
            if name == "shots":  # the columns the report does not read
                table = table.assign(hitter="near", intent="rally", outcome="ok", strike_x=0.0, strike_z=0.0,
                                     reveal_s=0.2, late_s=0.1)
            write_table(table, path, schema, prov)
            inputs[name].append(str(path))
    dataset = pd.concat(datasets, ignore_index=True)
    dataset = dataset.assign(**{c: 0 for c in DATASET.columns if c not in dataset})
    dataset.loc[dataset.index[-1], "split"] = "train"  # not a test hit: left out
    pred = pd.concat(preds, ignore_index=True).assign(a1=0.0, a2=0.0, b=0.0, region="centre")
    for name, table, schema in (("dataset", dataset, DATASET), ("predictions", pred, PREDICTIONS)):
        inputs[name] = str(tmp_path / f"{name}.parquet")
        write_table(table, inputs[name], schema, prov)
    out = Named(md=str(tmp_path / "o.md"), csv=str(tmp_path / "o.csv"), figure=str(tmp_path / "o.png"))
    stage.main(StageContext("report_uncertainty_oracle", inputs, out, {"sessions": ["s00", "s01"]}, None))
    md = (tmp_path / "o.md").read_text()
    assert "21 of 21 test hits matched" in md and "## Causes" in md and "(24 shots" in md
    csv = pd.read_csv(tmp_path / "o.csv")
    by_frame = csv[csv["table"] == "by_frame"]
    assert list(by_frame["frames_before_hit"]) == list(range(30, -1, -1)) and (by_frame["n_hits"] == 21).all()
    assert (by_frame["coverage_q05_q95"] == 1).all()  # labels at the oracle mean
    causes = csv[csv["table"] == "causes"]
    assert causes.loc[causes["cause"] == "all", "n_shots"].item() == 24
    assert (tmp_path / "o.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
