"""The learning stages' artifact layouts (light: no torch, so readers such as the robot do not hash the
training code)."""

from pingpong.common.artifacts import Schema

CV_RESULT = Schema("cv_result", 1)
SELECTION = Schema("model_selection", 1)
PREDICTIONS = Schema("predictions", 1, ("model", "session", "rally", "hit", "split", "frames_before_hit",
                                        "a1", "a2", "b", "strike_x_pred", "strike_x", "abs_error", "region"))
