"""Bridges that let a real autopilot binary fly our simulated world.

The autopilot (ArduCopter SITL, PX4 SITL) runs its own estimator and controllers and takes its
physics from us: `ardupilot_json` answers ArduPilot's JSON backend (servo frames in, a JSON
state line out, UDP 9002+10*I), `px4_hil` serves PX4's simulator_mavlink (HIL_SENSOR and
HIL_GPS out, HIL_ACTUATOR_CONTROLS in, TCP 4560+I). Both step a motor-driven PyBullet body
(`sim.vehicle.motor_quad`) in lockstep with the autopilot. `processes` starts and stops the
binaries; `world` puts the field, the targets, the truth record and the camera hook round them.
See docs/autopilots.md.
"""
