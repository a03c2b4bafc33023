"""Benchmark: the speed figures (simucal/bench.py, also `simucal bench`).
Usage: python3 benchmarks/bench_speed.py [--json OUT] [--before OLD.json] [--quick]
"""
import argparse

from simucal.bench import run

if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", default=None)
    ap.add_argument("--before", default=None)
    ap.add_argument("--quick", action="store_true",
                    help="every step at a size of seconds (its figures measure nothing)")
    args = ap.parse_args()
    run(args.json, before=args.before, size="quick" if args.quick else "full")
