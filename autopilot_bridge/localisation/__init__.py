"""Where the vehicle is: the GPS estimator, the telemetry intake (home, the local origin) and the
GPS-free registrations (the field's edge, the targets already found)."""
