"""Shared by the registration and found-target tests (test_registration.py, test_found.py): a
real vehicle standing on its spawn cell with the companion's parts on its link (`on_the_pad`),
and blobs at given offsets (`blob_at`)."""

from __future__ import annotations

import socket
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from autopilot_bridge.detection.detector import Blob, px_per_m
from autopilot_bridge.link.connection import VehicleLink
from autopilot_bridge.localisation.estimator import GpsEstimator
from autopilot_bridge.localisation.registration import Registration
from autopilot_bridge.localisation.telemetry import TelemetryIntake
from autopilot_bridge.service.search_data import SearchSpec
from sim.gridworld import GridConfig
from sim.mavlink import Sitl, SitlConfig


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def blob_at(offset_ne: tuple[float, float], height: float) -> Blob:
    """A whole (uncut) blob whose target lies offset_ne (north, east m) from the nadir."""
    k = px_per_m(height)
    return Blob(row=-offset_ne[0] * k, col=offset_ne[1] * k, pixels=200, cut=(False, False, False, False))


@dataclass
class Pad:
    """A real vehicle standing on its spawn cell, the companion's parts on its link, fixes fused
    up to t."""

    sitl: Sitl
    link: VehicleLink
    spec: SearchSpec
    estimator: GpsEstimator
    intake: TelemetryIntake
    reg: Registration
    t: float
    cell: np.ndarray


@contextmanager
def on_the_pad(instance: int) -> Iterator[Pad]:
    grid = GridConfig()
    sitl = Sitl(SitlConfig(instance=instance, speedup=4.0, physics="kinematic", camera=False, gcs_link=False,
                           api_local_port=free_port(), api_remote_port=free_port(), grid=grid)).start()
    link = VehicleLink(f"udpin:127.0.0.1:{sitl.cfg.api_ports[1]}")
    spec = SearchSpec(origin=sitl.field_origin, grid=grid)
    estimator = GpsEstimator()
    intake = TelemetryIntake(link, spec.origin, estimator, spec.arrive_m)
    try:
        link.wait_heartbeat()
        link.wait_for(lambda: len(intake.local_history) > 5 and intake.has_fixes(), 20, "telemetry")
        t = intake.local_history[-1][0]
        intake.fuse_until(t)
        cell = np.array([int(v) for v in sitl.episode.agent[0]])  # the vehicle stands on its spawn cell
        yield Pad(sitl, link, spec, estimator, intake, Registration(link, spec, estimator, intake), t, cell)
    finally:
        link.close()
        sitl.stop()
