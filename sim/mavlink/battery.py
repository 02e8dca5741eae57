"""The battery, whatever the airframe: a 4S LiPo drained on simulated time while armed (hover
draw in the air, a tenth of it on the ground), reported through the state's battery fields that
SYS_STATUS and BATTERY_STATUS read. Endurance is UAVS_BAT_ENDUR_S of hover from full, draining no lower than SIM_BAT_MIN_PCT
(50 %, PX4 SITL's default); the
failsafe thresholds are PX4's BAT_LOW_THR / BAT_CRIT_THR / BAT_EMERGEN_THR (failsafe.py)."""

from __future__ import annotations

from dataclasses import dataclass

CELLS = 4
V_EMPTY, V_CHARGED = 3.6, 4.05  # per cell, PX4's BAT_V_EMPTY / BAT_V_CHARGED defaults
GROUND_DRAW = 0.1  # armed on the ground: a tenth of the hover draw


@dataclass
class Battery:
    remaining: float = 1.0  # 0..1
    failed: bool = False  # MAV_CMD_INJECT_FAILURE battery OFF: reads empty

    def step(self, dt: float, armed: bool, in_air: bool, endurance_s: float, min_remaining: float = 0.0) -> None:
        """Drain; never below `min_remaining` (PX4 SITL's SIM_BAT_MIN_PCT: a long simulation
        must not end in a battery failsafe nobody asked for)."""
        if armed and endurance_s > 0 and self.remaining > min_remaining:
            drained = self.remaining - dt / endurance_s * (1.0 if in_air else GROUND_DRAW)
            self.remaining = max(min_remaining, drained, 0.0)

    @property
    def reading(self) -> float:
        return 0.0 if self.failed else self.remaining

    @property
    def voltage(self) -> float:
        return CELLS * (V_EMPTY + (V_CHARGED - V_EMPTY) * self.reading)
