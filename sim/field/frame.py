"""Grid cell <-> local NED for a grid at any heading and origin: `sim.gridworld.coords.GridFrame`.

Written once, in `sim.gridworld.coords`, beside today's north-aligned mapping it rotates and
shifts, so the SITL, the companion (which may not import `sim.field`) and the field module all
call the same function. Re-exported here, where the field module always found it; its bad
values raise `ValueError` (`FieldError` is one too)."""

from __future__ import annotations

from sim.gridworld.coords import GridFrame

__all__ = ["GridFrame"]
