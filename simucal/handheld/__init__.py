"""Hand-placed sessions (a continuous stream, no turntable): static-pose detection, the
accelerometer from the poses and the gyro from the moves between them, their simulator,
and the diagnosis of the moves."""
