"""AdamW (Loshchilov & Hutter 2019) with torch.optim.AdamW's defaults and arithmetic, op for op: its
single-tensor path, the one it takes on the CPU.

Written out, not imported, because every torch.optim optimiser imports torch's compiler stack
(torch._dynamo) when it is built and when it steps: on this 2-core machine `import torch` took 2.0-2.1 s
and `import torch, torch._dynamo` 3.5-4.4 s (2026-12-03, three runs each), a cost each of the ~30
training jobs of a run pays. tests/test_learning.py checks it against torch.optim.AdamW step for step,
bit for bit.
"""

import torch


class AdamW:
    """Decoupled weight decay Adam over `params` (those that require a gradient); the interface of
    torch.optim's that train() uses: `zero_grad()` and `step()`."""

    def __init__(self, params, lr: float, betas: tuple[float, float] = (0.9, 0.999), eps: float = 1e-8,
                 weight_decay: float = 1e-2):
        self.params = [p for p in params if p.requires_grad]
        self.lr, self.betas, self.eps, self.weight_decay = lr, betas, eps, weight_decay
        self.exp_avg = [torch.zeros_like(p, memory_format=torch.preserve_format) for p in self.params]
        self.exp_avg_sq = [torch.zeros_like(p, memory_format=torch.preserve_format) for p in self.params]
        self.steps = [0] * len(self.params)  # per parameter, as torch counts them: steps it had a gradient

    def zero_grad(self) -> None:
        for p in self.params:
            p.grad = None

    @torch.no_grad()
    def step(self) -> None:
        beta1, beta2 = self.betas
        for k, (p, m, v) in enumerate(zip(self.params, self.exp_avg, self.exp_avg_sq, strict=True)):
            if p.grad is None:
                continue
            self.steps[k] += 1
            step = float(self.steps[k])
            p.mul_(1 - self.lr * self.weight_decay)
            m.lerp_(p.grad, 1 - beta1)
            v.mul_(beta2).addcmul_(p.grad, p.grad, value=1 - beta2)
            step_size = self.lr / (1 - beta1**step)
            denom = (v.sqrt() / (1 - beta2**step) ** 0.5).add_(self.eps)
            p.addcdiv_(m, denom, value=-step_size)
