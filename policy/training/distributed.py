"""Training on more than one core, GPU or machine.

Two independent axes:
- folds are independent trainings: `run_jobs` fans them out over local processes, or over a
  ray cluster when an address is given (the dataset path must then be readable on every node);
- one fold over several GPUs: `spawn_ddp` starts one process per device and `init_ddp` joins
  them in a torch DistributedDataParallel group (NCCL on CUDA, gloo on CPU, which is what the
  tests exercise on a machine without GPUs).
"""

from __future__ import annotations

import os
import socket
from collections.abc import Callable, Sequence
from typing import Any

import torch
import torch.distributed as dist

from ..fanout import fan_out


def run_jobs(fn: Callable[..., Any], jobs: Sequence[tuple], workers: int | None = None,
             ray_address: str | None = None) -> list[Any]:
    """[fn(*job) for job in jobs] in parallel (local processes or ray); results in job order."""
    return fan_out(fn, jobs, workers=workers, ray_address=ray_address)


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def spawn_ddp(fn: Callable[..., Any], world: int, *args: Any) -> None:
    """Run fn(rank, world, port, *args) in `world` processes and wait for all of them."""
    if world < 2:
        raise ValueError(f"DDP needs at least 2 processes (got {world})")
    if torch.cuda.is_available() and torch.cuda.device_count() < world:
        raise ValueError(f"--ddp {world} asks for more processes than the {torch.cuda.device_count()} GPUs")
    torch.multiprocessing.spawn(fn, args=(world, free_port(), *args), nprocs=world, join=True)


def init_ddp(rank: int, world: int, port: int) -> torch.device:
    """Join the process group; each rank gets its own GPU when there are GPUs, else the CPU."""
    os.environ["MASTER_ADDR"] = "127.0.0.1"
    os.environ["MASTER_PORT"] = str(port)
    if torch.cuda.is_available():
        torch.cuda.set_device(rank)
        dist.init_process_group("nccl", rank=rank, world_size=world)
        return torch.device("cuda", rank)
    torch.set_num_threads(1)
    dist.init_process_group("gloo", rank=rank, world_size=world)
    return torch.device("cpu")


def close_ddp() -> None:
    if dist.is_initialized():
        dist.destroy_process_group()


def all_reduce_sum(values: list[float], device: torch.device) -> list[float]:
    """Sum python numbers over all ranks (identity without a process group)."""
    if not dist.is_initialized():
        return values
    t = torch.tensor(values, dtype=torch.float64, device=device)
    dist.all_reduce(t)
    return t.tolist()
