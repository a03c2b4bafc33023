"""ruan2019: three-position field calibration of the gyro constant drift, and its simulator."""
