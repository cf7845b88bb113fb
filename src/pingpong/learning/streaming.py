"""Frame-by-frame prediction for the robot loop: the recurrent state is carried between frames, so
each new camera frame costs one recurrent step instead of a pass over the whole history."""

import numpy as np
import torch

from pingpong.learning.models import AnticipationNet
from pingpong.learning.train import strike_points


class StreamingPredictor:
    """Feed one 39-value frame at a time with `step`; call `reset()` before each hit's first frame.

    After the frame at t = -k, `step` returns the prediction the batch pass makes at that frame
    (models.py, "Frame indexing"). Runs on the CPU in eval mode (moves the net there).
    """

    def __init__(self, net: AnticipationNet):
        self.net = net.cpu().eval()
        self.n_input = net.architecture["n_input"]
        self.reset()

    def reset(self) -> None:
        """Forget the current hit: the next frame starts a new sequence."""
        self._hidden = None
        self.n_frames = 0

    @torch.inference_mode()
    def step(self, frame: np.ndarray) -> tuple[np.ndarray, float]:
        """((a1, a2, b) float32 (3,), strike-point x in m) after this frame of 39 input values."""
        frame = np.asarray(frame, dtype=np.float32)
        if frame.shape != (self.n_input,) or not np.isfinite(frame).all():
            raise ValueError(f"StreamingPredictor.step: frame {self.n_frames} of the hit has shape "
                             f"{frame.shape}, finite={np.isfinite(frame).all()}; expected {self.n_input} "
                             "finite values (docs/architecture.md, the input layout)")
        params, self._hidden = self.net.step(torch.from_numpy(frame)[None], self._hidden)
        self.n_frames += 1
        params = params[0].numpy()
        return params, float(strike_points(params))
