"""Systematic calibration: a Kalman filter over a continuous rotation sequence (method systematic)."""
