"""simucal: strapdown IMU calibration (turntable and field), from derived models.

Runtime package: reads measurement sets (spec measurement-set.md), simulates,
calibrates, audits. It imports the generated modules (simucal.generated) and
never SymPy on the hot path.
"""
__version__ = "0.1.0"
