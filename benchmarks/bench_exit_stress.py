"""Stress: every command, a refusal and a success, run as whole processes many times; counts the runs
killed by a signal (a refused `apply` was once killed by SIGABRT at interpreter exit,
"terminate called without an active exception", a C++ library's thread still alive).

Each case must end with its expected exit status (0, or 2 for a refusal) every time; a run that a
signal ends (a negative status) or that ends otherwise is counted and its stderr's last line shown.
Two processes run at a time (this machine's cores).
Usage: python3 benchmarks/bench_exit_stress.py [--runs 200] [--only apply]
"""
import argparse
import json
import subprocess
import sys
import tempfile
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

# the console script beside this interpreter, as a user runs it (else the package by this interpreter)
SIMUCAL = [str(Path(sys.executable).with_name("simucal"))] if Path(sys.executable).with_name("simucal").is_file() \
    else [sys.executable, "-m", "simucal"]


def _prepare(tmp: Path):
    """Two units' raw sets (their serials stated), a field set, a still stream, a calibration of unit A."""
    def run(*args):
        subprocess.run([*SIMUCAL, *map(str, args)], check=True, capture_output=True)
    run("simulate", "-o", tmp / "a", "--rate-hz", "20", "--seed", "1")
    run("simulate", "-o", tmp / "b", "--rate-hz", "20", "--seed", "2")
    for name, serial in (("a", "A1"), ("b", "B2")):
        meta = json.loads((tmp / name / "meta.json").read_text())
        (tmp / name / "meta.json").write_text(json.dumps({**meta, "unit_serial": serial}, indent=2))
    run("simulate", "-o", tmp / "field", "--scenario", "field")
    run("calibrate", tmp / "a", "-o", tmp / "cal_a.json")
    from simucal.handheld.simulate import write_still
    write_still(tmp / "still", seconds=120.0)
    (tmp / "bad.py").write_text("MODELS = [\n")


def cases(t: Path) -> dict[str, tuple[int, list[str]]]:
    """name -> (the expected exit status, the arguments); every output in its own name under out/."""
    o = t / "out"
    return {
        "simulate ok": (0, ["simulate", "-o", o / "sim{i}", "--plan", "table1"]),
        "simulate refused": (2, ["simulate", "-o", t / "a"]),
        "import ok": (0, ["import", "csv", t / "a" / "samples.csv", "-o", o / "imp{i}", "--columns",
                          "t_s=t_s,ax=ax,ay=ay,az=az", "--acc-unit", "g"]),
        "import refused": (2, ["import", "csv", t / "a" / "samples.csv", "-o", o / "impr{i}"]),
        "apply ok": (0, ["apply", t / "cal_a.json", t / "a", "-o", o / "app{i}"]),
        "apply refused": (2, ["apply", t / "cal_a.json", t / "b", "-o", o / "appr{i}"]),
        "validate ok": (0, ["validate", t / "cal_a.json", t / "a", "-o", o / "v{i}.json"]),
        "validate refused": (2, ["validate", t / "cal_a.json", t / "b", "-o", o / "vr{i}.json"]),
        "noise ok": (0, ["noise", t / "still", "-o", o / "n{i}.json"]),
        "noise refused": (2, ["noise", t / "still", "-o", o / "nr{i}.json", "--html", o / "nr{i}.json"]),
        "calibrate ok": (0, ["calibrate", t / "a", "-o", o / "c{i}.json"]),
        "calibrate refused": (2, ["calibrate", t / "a", "--add", "acc.no_such_effect", "-o", o / "cr{i}.json"]),
        "field-drift ok": (0, ["field-drift", t / "field", "-o", o / "fd{i}.json"]),
        "field-drift refused": (2, ["field-drift", t / "a", "-o", o / "fdr{i}.json"]),
        "diagnose ok": (0, ["diagnose", t / "a", "-o", o / "d{i}.json"]),
        "diagnose refused": (2, ["diagnose", t / "a", "--add", t / "bad.py", "-o", o / "dr{i}.json"]),
        "montecarlo ok": (0, ["montecarlo", "--trials", "200", "-o", o / "mc{i}.json"]),
        "montecarlo refused": (2, ["montecarlo", "--effect", "acc.no_such_effect=1", "-o", o / "mcr{i}.json"]),
        "plan ok": (0, ["plan", "--score", "table1", "-o", o / "p{i}.json"]),
        "plan refused": (2, ["plan", "--score", "no_such_plan", "-o", o / "pr{i}.json"]),
        "derive refused": (2, ["derive", "--model", t / "bad.py"]),
        "audit refused": (2, ["audit", "-o", t / "a"]),
        "demo refused": (2, ["demo", "-o", t]),
        "bench refused": (2, ["bench", "-o", t / "a"]),
        "version ok": (0, ["--version"]),
    }


def one(job):
    name, code, args = job
    r = subprocess.run([*SIMUCAL, *map(str, args)], capture_output=True, text=True)
    last = (r.stderr.strip().splitlines() or [""])[-1]
    return name, r.returncode, code, last


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=200, help="runs of each case (default 200)")
    ap.add_argument("--only", default=None, help="run only the cases whose name starts with this, e.g. apply")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        _prepare(t)
        (t / "out").mkdir()
        chosen = {k: v for k, v in cases(t).items() if not args.only or k.startswith(args.only)}
        jobs = [(name, code, [str(a).format(i=i) for a in argv]) for i in range(args.runs)
                for name, (code, argv) in chosen.items()]
        ends, wrong = Counter(), {}
        with ThreadPoolExecutor(2) as pool:
            for name, rc, code, last in pool.map(one, jobs):
                ends[name, rc] += 1
                if rc != code:
                    wrong.setdefault((name, rc), last)
    print("| case | runs | exit expected/other | killed by a signal |\n|---|---|---|---|")
    for name, (code, _) in chosen.items():
        runs = sum(n for (k, _), n in ends.items() if k == name)
        signal = sum(n for (k, rc), n in ends.items() if k == name and rc < 0)
        other = sum(n for (k, rc), n in ends.items() if k == name and rc >= 0 and rc != code)
        print(f"| {name} | {runs} | {ends[name, code]}/{other} | {signal} |")
    for (name, rc), last in wrong.items():
        print(f"{name}: exit {rc}: {last}")
    deaths = sum(n for (_, rc), n in ends.items() if rc < 0)
    print(f"\n{sum(ends.values())} runs, {deaths} killed by a signal, {len(wrong)} cases with another exit")
    sys.exit(1 if deaths or wrong else 0)


if __name__ == "__main__":
    main()
