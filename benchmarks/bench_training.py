"""Network speed on this machine, both architectures side by side: training samples/s (and
one epoch over 400k 3x3 samples extrapolated), decision latency p50/p99 at batch 1 and
throughput at batch 256. Targets: an epoch < 60 s on 2 cores, p99 < 2 ms at batch 1 (small)."""

from __future__ import annotations

import time

import numpy as np
import torch

from policy.nn import ModelConfig, build_model


def train_rate(arch: str, steps: int) -> float:
    torch.manual_seed(0)
    cfg = ModelConfig(arch=arch)
    net = build_model(cfg)
    opt = torch.optim.SGD(net.parameters(), lr=1e-3, momentum=0.9)
    v = torch.randint(0, 2, (64, 3, 3, 3), dtype=torch.uint8)
    m = (torch.rand(64, 1, 10, 10) * 10).round()
    y = torch.randint(0, 4, (64,))
    for _ in range(3):
        loss, _ = net.loss(v, m, y)
        opt.zero_grad()
        loss.backward()
        opt.step()
    t0 = time.perf_counter()
    for _ in range(steps):
        loss, _ = net.loss(v, m, y)
        opt.zero_grad()
        loss.backward()
        opt.step()
    return 64 * steps / (time.perf_counter() - t0)


@torch.inference_mode()
def latency(arch: str, n: int = 400) -> tuple[float, float, float]:
    net = build_model(ModelConfig(arch=arch)).eval()
    v1, m1 = torch.zeros(1, 3, 3, 3, dtype=torch.uint8), torch.zeros(1, 1, 10, 10)
    for _ in range(20):
        net(v1, m1)
    ts = []
    for _ in range(n):
        t0 = time.perf_counter()
        net(v1, m1).argmax(1)
        ts.append(time.perf_counter() - t0)
    vb, mb = torch.zeros(256, 3, 3, 3, dtype=torch.uint8), torch.zeros(256, 1, 10, 10)
    t0 = time.perf_counter()
    for _ in range(20):
        net(vb, mb).argmax(1)
    thr = 256 * 20 / (time.perf_counter() - t0)
    return 1e3 * np.percentile(ts, 50), 1e3 * np.percentile(ts, 99), thr


def main() -> None:
    print(f"torch {torch.__version__}, {torch.get_num_threads()} threads, CUDA: {torch.cuda.is_available()}")
    small, paper = train_rate("small", 300), train_rate("paper", 20)
    print(f"training samples/s  small {small:,.0f}  paper {paper:,.0f}  ratio {small / paper:.0f}x")
    print(f"epoch of 400k 3x3 samples: small {400_000 / small:.0f} s, paper {400_000 / paper:.0f} s (target < 60 s)")
    for arch in ("small", "paper"):
        p50, p99, thr = latency(arch, 400 if arch == "small" else 100)
        print(f"{arch:<6} decision latency batch 1: p50 {p50:.3f} ms, p99 {p99:.3f} ms; batch 256: {thr:,.0f} decisions/s")


if __name__ == "__main__":
    main()
