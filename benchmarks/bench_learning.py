"""Speed of the learning stage, measured against baselines in the same run.

1. Streaming latency per frame (budget: 10 ms, one camera frame at 100 Hz) of StreamingPredictor
   against what a naive robot loop would do: re-run the whole history through the net at every
   new frame and keep the last output. Both produce the same prediction (checked).
2. Training throughput (sequences/s through train(), validation included) of the default-size
   model on fixed-length sequences against variable-length (front-padded) ones.

Runs on the CPU with --threads torch threads (default 1: a robot loop would pin one core, and
single-sample steps gain nothing from more).

    PYTHONPATH=src python benchmarks/bench_learning.py [--frames 100] [--hits 3] [--train-n 2000]
"""

import argparse
import time

import numpy as np
import torch

from pingpong.common.seeding import rng_for
from pingpong.frames import N_INPUT
from pingpong.learning.models import AnticipationNet
from pingpong.learning.streaming import StreamingPredictor
from pingpong.learning.train import train

SIZES = {
    "default (GRU 64x2, MLP 128x2)": dict(cell="gru", rnn_hidden=64, rnn_layers=2, mlp_hidden=128,
                                          mlp_layers=2),
    "paper (GRU 400x4, MLP 1200x5)": dict(cell="gru", rnn_hidden=400, rnn_layers=4, mlp_hidden=1200,
                                          mlp_layers=5),
}


def streaming_latency(net, hits: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-frame seconds of StreamingPredictor.step and of the naive full re-forward, same frames."""
    stream = StreamingPredictor(net)
    t_stream, t_naive = [], []
    with torch.inference_mode():
        for hit in hits:
            stream.reset()
            history = torch.from_numpy(hit)
            for i, frame in enumerate(hit):
                start = time.perf_counter()
                params, _ = stream.step(frame)
                t_stream.append(time.perf_counter() - start)
                start = time.perf_counter()
                naive = net(history[None, : i + 1])[0, -1]
                t_naive.append(time.perf_counter() - start)
                assert np.allclose(params, naive.numpy(), atol=1e-4), "streaming and re-forward disagree"
    return np.array(t_stream), np.array(t_naive)


def training_throughput(arch: dict, X, Y, lengths, epochs: int) -> float:
    """Sequences per second through train() (a fixed small validation set included)."""
    net = AnticipationNet(**arch)
    start = time.perf_counter()
    train(net, X, Y, X[:50], Y[:50], lr=1e-3, max_epochs=epochs, patience=epochs, seed=0, device="cpu",
          lengths_train=lengths, lengths_val=None if lengths is None else lengths[:50], progress=False)
    return len(X) * epochs / (time.perf_counter() - start)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=100, help="frames per streamed hit (1 s at 100 Hz)")
    parser.add_argument("--hits", type=int, default=3, help="hits streamed per model size")
    parser.add_argument("--train-n", type=int, default=2000, help="training sequences")
    parser.add_argument("--train-frames", type=int, default=60, help="frames per training sequence")
    parser.add_argument("--epochs", type=int, default=3)
    parser.add_argument("--threads", type=int, default=1, help="torch intra-op threads")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    rng = rng_for(0, "bench_learning")
    print(f"torch {torch.__version__}, {torch.get_num_threads()} threads, CPU\n")

    print("| model | streaming ms/frame (mean / p99) | re-forward ms/frame (mean / p99) | speed-up | "
          "within 10 ms budget (p99) |")
    print("|---|---|---|---|---|")
    hits = rng.normal(size=(args.hits, args.frames, N_INPUT)).astype(np.float32)
    for name, arch in SIZES.items():
        net = AnticipationNet(**arch).eval()
        net.normaliser.fit(hits)
        stream, naive = streaming_latency(net, hits)
        ms = lambda t: f"{1e3 * t.mean():.3f} / {1e3 * np.percentile(t, 99):.3f}"  # noqa: E731
        print(f"| {name} | {ms(stream)} | {ms(naive)} | {naive.mean() / stream.mean():.1f}x | "
              f"{'yes' if np.percentile(stream, 99) < 0.010 else 'NO'} |")

    X = rng.normal(size=(args.train_n, args.train_frames, N_INPUT)).astype(np.float32)
    Y = rng.normal(scale=0.3, size=(args.train_n, 3)).astype(np.float32)
    lengths = rng.integers(31, args.train_frames + 1, size=args.train_n)
    arch = next(iter(SIZES.values()))
    fixed = training_throughput(arch, X, Y, None, args.epochs)
    padded = training_throughput(arch, X, Y, lengths, args.epochs)
    print(f"\n| training, default model, T={args.train_frames}, batch 500 | sequences/s | ratio |")
    print("|---|---|---|")
    print(f"| fixed length (baseline) | {fixed:.0f} | 1.00 |")
    print(f"| variable length (front-padded, lengths 31..{args.train_frames}) | {padded:.0f} | "
          f"{padded / fixed:.2f} |")


if __name__ == "__main__":
    main()
