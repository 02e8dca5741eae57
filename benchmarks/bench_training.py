"""Network speed on this machine, both architectures side by side: training samples/s (and
one epoch over 400k 3x3 samples extrapolated), decision latency p50/p99 at batch 1 through
NetworkPolicy.decide (eager and TorchScript) and throughput at batch 256.
Targets for the small default: an epoch < 60 s on 2 cores, p99 < 2 ms at batch 1.

    .venv/bin/python benchmarks/bench_training.py [threads (default 1)]
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from policy.nn import ModelConfig, NetworkPolicy, build_model, export_torchscript, load_torchscript

SAMPLES_PER_EPOCH = 400_000


def train_rate(arch: str, steps: int, batch: int = 64) -> float:
    """Samples/s of the real training step (SGD momentum, the model's own loss) at batch 64."""
    torch.manual_seed(0)
    net = build_model(ModelConfig(arch=arch)).train()
    opt = torch.optim.SGD(net.parameters(), lr=1e-3, momentum=0.9)
    v = torch.randint(0, 2, (batch, 3, 3, 3), dtype=torch.uint8)
    m = (torch.rand(batch, 1, 10, 10) * 10).round()
    y = torch.randint(0, 4, (batch,))

    def step() -> None:
        loss, _ = net.loss(v, m, y)
        opt.zero_grad()
        loss.backward()
        opt.step()

    for _ in range(3):
        step()
    t0 = time.perf_counter()
    for _ in range(steps):
        step()
    return batch * steps / (time.perf_counter() - t0)


def latency(policy: NetworkPolicy, n: int) -> tuple[float, float]:
    view = np.zeros((3, 3, 3), dtype=np.uint8)
    grid_map = np.zeros((1, 10, 10), dtype=np.float32)
    for _ in range(20):
        policy.decide(view, grid_map)
    ts = np.empty(n)
    for i in range(n):
        t0 = time.perf_counter()
        policy.decide(view, grid_map)
        ts[i] = time.perf_counter() - t0
    return 1e3 * float(np.percentile(ts, 50)), 1e3 * float(np.percentile(ts, 99))


def throughput(policy: NetworkPolicy, batch: int = 256, reps: int = 20) -> float:
    views = np.zeros((batch, 3, 3, 3), dtype=np.uint8)
    maps = np.zeros((batch, 1, 10, 10), dtype=np.float32)
    policy.scores(views, maps)
    t0 = time.perf_counter()
    for _ in range(reps):
        policy.scores(views, maps).argmax(1)
    return batch * reps / (time.perf_counter() - t0)


def main(threads: int = 1) -> None:
    torch.set_num_threads(threads)
    print(f"torch {torch.__version__}, {torch.get_num_threads()} thread(s), CUDA: {torch.cuda.is_available()}, "
          f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    small, paper = train_rate("small", 300), train_rate("paper", 15)
    print(f"training samples/s   small {small:>9,.0f}   paper {paper:>7,.0f}   small/paper {small / paper:.0f}x")
    print(f"epoch of 400k 3x3 samples: small {SAMPLES_PER_EPOCH / small:.0f} s (target < 60 s), "
          f"paper {SAMPLES_PER_EPOCH / paper:.0f} s")
    with tempfile.TemporaryDirectory() as d:
        for arch in ("small", "paper"):
            cfg = ModelConfig(arch=arch)
            net = build_model(cfg).eval()
            script = load_torchscript(export_torchscript(net, cfg, Path(d) / f"{arch}.ts"))
            n = 2000 if arch == "small" else 200
            for kind, model in (("eager", net), ("torchscript", script)):
                policy = NetworkPolicy(model, arch)
                p50, p99 = latency(policy, n)
                print(f"{arch:<6} {kind:<12} batch 1: p50 {p50:.3f} ms, p99 {p99:.3f} ms (target < 2 ms); "
                      f"batch 256: {throughput(policy):>9,.0f} decisions/s")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:]))
