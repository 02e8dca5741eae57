"""Geodesy lives with the field's frames (sim.gridworld.geodesy) so the companion computer
can use the same conversion; re-exported here for the vehicle's code."""

from sim.gridworld.geodesy import HomePosition, from_e7, to_e7

__all__ = ["HomePosition", "from_e7", "to_e7"]
