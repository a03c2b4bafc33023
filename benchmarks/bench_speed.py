"""Benchmark: the speed figures of issue 14 (simucal/bench.py, also `simucal bench`).
Usage: python3 benchmarks/bench_speed.py [--json OUT]
"""
import argparse

from simucal.bench import run

if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", default=None)
    run(ap.parse_args().json)
