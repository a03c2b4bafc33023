"""Every command the README and the docs (docs/**/*.md) show runs (5 of its 8 benchmark commands
crashed and no test ran benchmarks/). Their code blocks are read here, not copied: a block whose commands hold
no placeholder runs as written, in order, in a fresh folder; the benchmarks run at a small size
(their size options below), each its own test; a block of placeholders (DIR, [--option], a|b) is a
reference, and each of its commands and options must exist."""
import re
import subprocess
import sys
from pathlib import Path

import click
import pytest
from click.testing import CliRunner

from simucal.cli import main

ROOT = Path(__file__).resolve().parents[1]


def _blocks(text):
    """The README's fenced code blocks, as text."""
    blocks, current = [], None
    for line in text.splitlines():
        if line.startswith("```") and current is None:
            current = []
        elif line.startswith("```"):
            blocks.append("\n".join(current))
            current = None
        elif current is not None:
            current.append(line)
    return blocks


PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
BLOCKS = [b for page in PAGES for b in _blocks(page.read_text())]
# each benchmark at a size of seconds: its own size option (the script's docstring names it)
SMALL = {"bench_derive_and_solve.py": ["--quick"], "bench_paper_tables.py": ["--seeds", "2"],
         "bench_unification.py": ["--seeds", "1"], "bench_unknown_noise.py": ["--seeds", "1"],
         "bench_speed.py": ["--quick"], "bench_field.py": ["--seeds", "1"], "bench_imu_tk.py": ["--repeats", "1"],
         "bench_imucal.py": [], "bench_exit_stress.py": ["--runs", "2", "--only", "apply"],
         "bench_allan.py": ["--seeds", "1", "--hours", "0.25", "--rate-hz", "5"],
         "bench_stds_by_rate.py": ["--seeds", "1", "--rates", "20"], "bench_thermal.py": ["0", "1"],
         "bench_temperature_rate.py": ["--seeds", "2", "--lag-seeds", "1"],
         "bench_cache_checks.py": [], "bench_lot.py": ["6", "--seeds", "2", "--workers", "2"],
         "bench_store.py": ["--records", "200", "--adds", "3", "--repeats", "1"],
         "bench_raw400.py": ["--rate-hz", "5", "--repeats", "1"], "bench_compare.py": ["--quick", "--repeats", "1"],
         "bench_warmup.py": ["--seeds", "1", "--minutes", "5", "--imus", "2"],
         "bench_family.py": ["--seeds", "2", "--auto-seeds", "1"], "bench_bag_noise.py": ["--hours", "0.02"],
         "bench_long_noise.py": ["--hours", "0.05", "--rate-hz", "50"],
         "bench_systematic.py": ["--seeds", "1", "--speed-hours", "0", "--compare-seeds", "0"],
         "bench_sequence_design.py": ["--minutes", "5", "--evaluations", "3", "--seeds", "1", "--units", "mems",
                                      "--table", "--table-minutes", "5", "--reference-minutes", "5",
                                      "--table-evaluations", "3"],
         "bench_scale.py": ["--rate-hz", "5", "--repeats", "0", "--hours", "0.005", "--lot", "2",
                            "--thermal-rate-hz", "1"]}
# what CI does by being CI: the installation, the suite itself, and the stale check (tests/test_generated.py
# runs derive --check's function); the demo (minutes of work, tests/test_loop.py and the others run its parts)
BY_CI = ("pip install", "python3 -m pip install", "python3 -m pytest", "simucal derive --check", "simucal demo")
PLACEHOLDER = re.compile(r"\[|\||\.\.\.|(?<![\w.-])[A-Z][A-Z0-9_]*(?:,[A-Z0-9_]+)*(?![\w.-])")


def _commands(block):
    """The block's commands: continuation lines joined, comments and `&&` split off."""
    lines = []
    for line in block.splitlines():
        if line.startswith((" ", "\t")) and lines:
            lines[-1] += " " + line.strip()
        elif line.strip():
            lines.append(line)
    return [c.strip() for line in lines for c in re.sub(r"\s+#.*$", "", line).split("&&") if c.strip()]


def _shell_blocks():
    """The blocks of commands (not the model files' Python)."""
    return [_commands(b) for b in BLOCKS if _commands(b) and all(
        c.startswith(("simucal ", "python3 ", "pip ")) for c in _commands(b))]


BENCHES = [c for b in _shell_blocks() for c in b if c.startswith("python3 benchmarks/")]
RUNNABLE = [c for b in _shell_blocks() if not any(PLACEHOLDER.search(c) for c in b) for c in b
            if not c.startswith(BY_CI) and c.startswith("simucal ")]
REFERENCE = [c for b in _shell_blocks() if any(PLACEHOLDER.search(c) for c in b) for c in b
             if c.startswith("simucal ")]


def test_the_readme_is_read():
    assert len(BENCHES) == len(SMALL) and len(RUNNABLE) >= 7 and len(REFERENCE) >= 20, (BENCHES, RUNNABLE)
    assert sorted(p.name for p in (ROOT / "benchmarks").glob("*.py")) == sorted(SMALL), "a benchmark the README lacks"


@pytest.mark.slow
@pytest.mark.parametrize("command", BENCHES)
def test_every_benchmark_in_the_readme_runs(command):
    """Each its own test, so that the two processes of the suite share them out as they come free."""
    script = command.split()[1]
    r = subprocess.run([sys.executable, script, *SMALL[Path(script).name]], cwd=ROOT, capture_output=True,
                       text=True, timeout=300)
    tail = (r.stdout + r.stderr)[-2000:]
    assert r.returncode == 0, tail
    assert "| " in r.stdout, tail  # each prints its table (a Dask cluster's close may log to stderr after it)


@pytest.mark.slow
def test_the_readme_loop_runs_as_written(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for command in RUNNABLE:
        r = CliRunner().invoke(main, command.split()[1:])
        assert r.exit_code == 0, (command, r.output)
    assert (tmp_path / "v.html").is_file() and (tmp_path / "calibrated" / "samples.csv").is_file()


def _options(command):
    return {o for p in command.params for o in p.opts + p.secondary_opts}


@pytest.mark.parametrize("command", REFERENCE)
def test_every_command_of_the_reference_exists_with_its_options(command):
    words = command.split()
    cmd = main.commands.get(words[1])
    if isinstance(cmd, click.Group):  # simucal store add: the subcommand's options
        cmd = cmd.commands.get(words[2])
    assert isinstance(cmd, click.Command), command
    given = set(re.findall(r"(?<![\w-])(--?[a-z][a-z0-9-]*)", command))
    assert given <= _options(cmd) | {"--help"}, (command, given - _options(cmd))
    if words[1] == "import":  # its formats, a|b|c
        assert set(words[2].split("|")) <= set(cmd.params[0].type.choices), command


def test_simucal_runs_as_a_module_without_the_script_on_path(tmp_path):
    r = subprocess.run([sys.executable, "-m", "simucal", "--version"], capture_output=True, text=True,
                       env={"PATH": str(tmp_path)})  # nothing named simucal on PATH
    assert r.returncode == 0 and "version" in r.stdout, r.stderr
