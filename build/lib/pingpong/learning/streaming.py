"""Frame-by-frame prediction for the robot loop: the recurrent state is carried between frames, so
each new camera frame costs one recurrent step instead of a pass over the whole history.

With causal inputs (curation.dataset) the predictor takes the measurements themselves: it runs the
dataset's forwards-only low-pass (curation.causal.CausalLowpass) on every frame it observes, from the
session's start on, holds the last filtered value through a dropout as the dataset's forward fill does,
and feeds the net from each hit's first frame. Its predictions then equal the batch pass on the dataset's
inputs (tests/test_streaming.py).
"""

import numpy as np
import torch

from pingpong.curation.causal import CausalLowpass
from pingpong.learning.models import AnticipationNet
from pingpong.learning.train import strike_points


class StreamingPredictor:
    """Feed one 39-value frame at a time with `step`; call `reset()` before each hit's first frame.

    After the frame at t = -k, `step` returns the prediction the batch pass makes at that frame
    (models.py, "Frame indexing"). input_filter: None (frames are the model's inputs already) or the
    CausalLowpass of the causal inputs (frames are measurements, NaN where missing; `observe` also feeds
    it the frames between hits). Runs on the CPU in eval mode (moves the net there).
    """

    def __init__(self, net: AnticipationNet, input_filter: CausalLowpass | None = None):
        self.net = net.cpu().eval()
        self.n_input = net.architecture["n_input"]
        self.input_filter = input_filter
        self._last = np.full(self.n_input, np.nan)
        self.reset()

    def reset(self) -> None:
        """Forget the current hit: the next frame starts a new sequence (the input filter runs on)."""
        self._hidden = None
        self.n_frames = 0

    def observe(self, frame: np.ndarray) -> np.ndarray:
        """The model input (39,) of one measured frame: filtered, and held where unmeasured (NaN before a
        value was ever seen). Without an input filter, the frame itself."""
        frame = np.asarray(frame, dtype=float)
        if self.input_filter is None:
            return frame
        filtered = self.input_filter.step(frame)
        self._last = np.where(np.isfinite(filtered), filtered, self._last)
        return self._last.copy()

    @torch.inference_mode()
    def step(self, frame: np.ndarray) -> tuple[np.ndarray, float]:
        """((a1, a2, b) float32 (3,), strike-point x in m) after this frame of 39 values."""
        frame = self.observe(frame).astype(np.float32)
        if frame.shape != (self.n_input,) or not np.isfinite(frame).all():
            raise ValueError(f"StreamingPredictor.step: frame {self.n_frames} of the hit has shape "
                             f"{frame.shape}, finite={np.isfinite(frame).all()}; expected {self.n_input} "
                             "finite values (docs/architecture.md, the input layout)")
        params, self._hidden = self.net.step(torch.from_numpy(frame)[None], self._hidden)
        self.n_frames += 1
        params = params[0].numpy()
        return params, float(strike_points(params))
