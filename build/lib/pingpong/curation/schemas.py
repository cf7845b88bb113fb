"""The curation stages' table layouts (light: no stage code, so readers do not hash the stages)."""

from pingpong.common.artifacts import Schema

EVENT_COLUMNS = ("kind", "index", "time_ns", "player", "side", "x", "y", "z")
EVENTS = Schema("ball_events", 1, EVENT_COLUMNS)
CURATION_RULES = ("net", "out", "double_bounce", "no_strike_line", "few_points", "no_incoming",
                  "short_history", "ball_gaps", "pose_gaps", "paddle_gaps")
CANDIDATE_COLUMNS = (  # find_segments
    "session", "hit", "hitter", "t_hit_ns", "hit_frame", "start_frame", "end_frame", "flight_end_frame",
    "post_bounce_sides", "n_opponent_bounces", "crosses_net", "reaches_strike_line", "n_path_points")
SEGMENTS = Schema("segments", 1, (  # curate_segments
    *CANDIDATE_COLUMNS, "rally", "ball_missing_frames", "joint_missing_frames", "paddle_missing_frames",
    "a1", "a2", "b", "strike_x", "strike_z", "strike_x_labels", "region", "decision", "reasons"))
DATASET = Schema("dataset", 1, (
    "session", "rally", "hit", "hitter", "t_hit_ns", "hit_frame", "n_frames", "x", "n_filled_frames",
    "a1", "a2", "b", "strike_x", "strike_z", "strike_x_labels", "region", "split", "fold"))
