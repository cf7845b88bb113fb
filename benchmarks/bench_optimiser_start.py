"""A training process's start: torch.optim.AdamW with the deterministic switch (what train() used before
2c7b8d6) against `pingpong.learning.adamw.AdamW` without it, each in fresh Python processes, alternated.

Both import torch, build a GRU net and take one optimiser step; the first also imports torch's compiler
stack (torch._dynamo), which torch.optim and torch.use_deterministic_algorithms pull in. Every training
job of the pipeline is such a process.

    PYTHONPATH=src python benchmarks/bench_optimiser_start.py [--runs 5]
"""

import argparse

from timing import fresh_process_medians

STEP = """
import torch
net = torch.nn.GRU(39, 64, batch_first=True)
{setup}
out, _ = net(torch.randn(8, 40, 39))
out.square().mean().backward()
opt.step()
"""
SIDES = {
    "torch.optim.AdamW + use_deterministic_algorithms": STEP.format(
        setup="torch.use_deterministic_algorithms(True, warn_only=True)\n"
              "opt = torch.optim.AdamW(net.parameters(), lr=3e-3)"),
    "pingpong.learning.adamw.AdamW": STEP.format(
        setup="from pingpong.learning.adamw import AdamW\nopt = AdamW(net.parameters(), lr=3e-3)"),
}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    a = ap.parse_args()
    medians = fresh_process_medians(SIDES, a.runs)
    baseline, ours = medians.values()
    print(f"| process (median of {a.runs}) | s |\n|---|---:|")
    for name, s in medians.items():
        print(f"| {name} | {s:.2f} |")
    print(f"| speed-up | {baseline / ours:.2f}x |")


if __name__ == "__main__":
    main()
