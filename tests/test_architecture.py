"""The package's shape: no import circles, every import runs down the layers, and the
runtime neither imports SymPy nor writes into the package when it calibrates,
diagnoses or applies (docs/architecture.md)."""
import ast
import hashlib
import json
import subprocess
import sys
import typing
from pathlib import Path

import pytest

import simucal

ROOT = Path(simucal.__file__).parent
# Lower layers first; a module may import from its own layer's package and from lower layers.
# The methods sit side by side and never import each other.
LAYERS = [
    {"simucal.errors", "simucal.sweeps", "simucal.progress", "simucal.generated", "simucal.version",
     "simucal.arguments", "simucal.notebook", "simucal.kinds"},
    {"simucal.io"},
    {"simucal.fit"},
    {"simucal.turntable", "simucal.handheld", "simucal.field", "simucal.systematic"},
    {"simucal.options"},  # calibrate's options, which the registry's methods read
    {"simucal.methods"},
    {"simucal.report"},
    {"simucal.bench", "simucal.derive_cmd"},
    {"simucal.store"},  # a lab's records: calibration files and their history (report/lot_figures' drift)
    {"simucal.api"},  # each verb's one home (the demo too: simucal.api.demo_run)
    {"simucal.cli"},
    {"simucal.__main__"},  # python -m simucal
]
DERIVES = {"simucal.derive_cmd", "simucal.fit.catalog", "simucal.report.paper_claims"}  # SymPy on purpose


def _group(module: str) -> str:
    parts = module.split(".")
    return ".".join(parts[:2])


def _layer(module: str) -> int:
    return next(i for i, names in enumerate(LAYERS) if _group(module) in names)


def _module_of(name: str) -> str:
    """An imported name as the module it is: simucal.io.units where that is a module, else the package
    (simucal.io's units, a name it defines); a name of the package's face (simucal.calibrate, the function) is
    the face, "simucal"."""
    parts = name.split(".")
    if parts[1:2] in (["derive"], ["generated"]):  # installed under simucal from the repository's top
        return ".".join(parts[:2])
    for k in range(len(parts), 1, -1):
        if ROOT.parent.joinpath(*parts[:k]).with_suffix(".py").exists() or \
                ROOT.parent.joinpath(*parts[:k], "__init__.py").exists():
            return ".".join(parts[:k])
    return "simucal"


def _deps(source: str) -> set[str]:
    """The simucal modules a module's source imports, in every form: import simucal.x, from simucal.x import y
    (y a module or a name), from simucal import y, importlib.import_module("simucal.x"), and inside functions."""
    deps = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "simucal":
            deps |= {_module_of(f"{node.module}.{a.name}") for a in node.names}
        elif isinstance(node, ast.Import):
            deps |= {_module_of(a.name) for a in node.names if a.name.split(".")[0] == "simucal"}
        elif (isinstance(node, ast.Call) and getattr(node.func, "attr", getattr(node.func, "id", "")) == "import_module"
              and node.args and isinstance(node.args[0], ast.Constant)
              and str(node.args[0].value).startswith("simucal")):
            deps.add(_module_of(node.args[0].value))
        elif isinstance(node, ast.Call) and getattr(node.func, "attr", getattr(node.func, "id", "")) == "import_module":
            deps.add("simucal.generated")  # a generated module by its name (fit/models.py): the only dynamic one
    return deps


def _imports() -> dict:
    out = {}
    for p in ROOT.rglob("*.py"):
        rel = p.relative_to(ROOT.parent).with_suffix("")
        name = ".".join(rel.parts[:-1] if rel.name == "__init__" else rel.parts)
        out[name] = _deps(p.read_text())
    return out


def _wrong(graph: dict) -> list[str]:
    """Every import that runs up the layers, or sideways between methods, or reaches SymPy at run time."""
    wrong = []
    for mod, deps in graph.items():
        for d in deps:
            if d == "simucal.derive":
                if mod not in DERIVES:
                    wrong.append(f"{mod} imports {d} (SymPy at run time)")
                continue
            if d == "simucal":  # the package's face: only the command line's entry and its own modules above it
                if _group(mod) not in ("simucal.cli", "simucal.__main__"):
                    wrong.append(f"{mod} imports the package's face (simucal's __init__): import the module itself")
                continue
            if _group(d) == _group(mod):
                continue
            lo, hi = _layer(d), _layer(mod)
            if lo > hi or (lo == hi and lo > 0):
                wrong.append(f"{mod} (layer {hi}) imports {d} (layer {lo})")
    return wrong


def test_imports_run_down_the_layers_without_circles():
    graph = _imports()
    # the package's face: __version__ and the Python API's names, imported on first use (README, Python API)
    assert graph.pop("simucal") <= {"simucal.version", "simucal.api"}
    wrong = _wrong(graph)
    assert not wrong, "\n".join(wrong)
    # circles among modules (the layer rule already forbids them between packages)
    mods = {m: {d for d in deps if d in graph and d != m} for m, deps in graph.items()}
    state, circles = {}, []

    def visit(m, stack):
        state[m] = 1
        for d in mods[m]:
            if state.get(d) == 1:
                circles.append(stack[stack.index(d):] + [d])
            elif d not in state:
                visit(d, stack + [d])
        state[m] = 2
    for m in mods:
        if m not in state:
            visit(m, [m])
    assert not circles, circles


@pytest.mark.parametrize("source", [
    "from simucal import calibrate",                      # a name of the face
    "from simucal import cli",                            # a module through the package
    "from simucal.report.console import calibration_lines",
    "import simucal.api.tools",
    "def f():\n    import importlib\n    return importlib.import_module('simucal.methods')",
    "import simucal"])
def test_the_layer_rule_sees_every_import_form(source):
    """An arrow up planted in simucal/fit (layer 2) in each form of import is found."""
    assert _wrong({"simucal.fit.planted": _deps(source)}), source


def test_every_subpackage_is_installed():
    import tomllib
    listed = set(tomllib.loads((ROOT.parent / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {".".join(p.parent.relative_to(ROOT.parent).parts) for p in ROOT.rglob("__init__.py")}
    assert found <= listed, f"add {sorted(found - listed)} to pyproject.toml's packages"


def _package_digest():
    h = hashlib.sha256()
    for p in sorted(ROOT.parent.glob("generated/*")) + sorted(ROOT.rglob("*")):
        if p.is_file() and "__pycache__" not in p.parts:
            h.update(str(p).encode() + p.read_bytes())
    return h.hexdigest()


@pytest.mark.slow
def test_runtime_imports_no_sympy_and_writes_nothing_into_the_package(tmp_path):
    before = _package_digest()
    script = f"""
import json, sys
from pathlib import Path
from simucal.turntable.simulate import SCENARIOS, write
from simucal.api.calibrating import calibrate
from simucal.api.diagnosing import diagnosis_report as diagnose
from simucal.fit.apply import apply
from simucal.io import calibration
tmp = Path({str(tmp_path)!r})
write(tmp / "set", SCENARIOS["paper"](), seed=1)
assert "sympy" not in sys.modules
calibration.save(tmp / "cal.json", calibrate(tmp / "set"))
diagnose(tmp / "set")
apply(calibration.load(tmp / "cal.json"), tmp / "set")
print(json.dumps(sorted(m for m in sys.modules if m.split(".")[0] == "sympy")))
"""
    res = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr[-2000:]
    assert json.loads(res.stdout.strip().splitlines()[-1]) == []
    assert _package_digest() == before


def test_the_architecture_page_names_every_module_and_the_readme_every_folder():
    """docs/architecture.md's table has a row per folder naming each of its modules; the README's layout one
    short row per folder (it fits on a screen: under 200 characters a row)."""
    import re
    page = (ROOT.parent / "docs" / "architecture.md").read_text()
    readme = (ROOT.parent / "README.md").read_text()
    missing = []
    for folder in [ROOT] + [p.parent for p in ROOT.glob("*/__init__.py")]:
        rel = folder.relative_to(ROOT.parent).as_posix()
        row = re.search(rf"^\| `{rel}/` \|(.*)$", page, re.M)
        assert row, f"docs/architecture.md's table has no row for {rel}/"
        named = set(re.findall(r"`([\w]+\.py)`", row.group(1))) - {"__init__.py"}
        files = {p.name for p in folder.glob("*.py")} - {"__init__.py"}
        missing += [f"{rel}/{f}" for f in sorted(files ^ named)]
        short = re.search(rf"^\| `{rel}/` \|(.*)$", readme, re.M)
        assert short and len(short.group(0)) < 200, f"README's layout: one short row for {rel}/"
    assert not missing, f"docs/architecture.md's table and the tree differ on {missing}"


def test_one_method_registry():
    """Every calibration method is named once (simucal/methods.py); the cli's --method, the demo and
    the paper's claims read it, and no other module spells the list of methods."""
    from click.testing import CliRunner

    from simucal import methods
    from simucal.cli import main
    from simucal.report import paper_claims
    assert paper_claims.METHODS == ("exact", "linear", "multiposition")
    assert methods.for_data(methods.TURNTABLE) == paper_claims.METHODS + ("ferraris",)
    help_text = CliRunner().invoke(main, ["calibrate", "--help"]).output
    assert all(m in help_text for m in ("auto",) + methods.NAMES)
    assert {m.data for m in methods.METHODS.values()} == set(methods.DATA)
    spelled = [p.relative_to(ROOT) for p in ROOT.rglob("*.py") if p.name != "methods.py"
               and "generated" not in p.parts and '"exact", "linear", "multiposition"' in p.read_text()]
    # but a type checker's Literal of the options (options.py), which must be spelt out: it is the registry's
    from simucal.options import Method
    assert spelled == [Path("options.py")] and set(typing.get_args(Method)) == {"auto", *methods.NAMES}
    from simucal.api.imports import FORMATS, Format  # and the other names an editor checks, each its registry's
    from simucal.api.simulation import ScenarioName
    from simucal.cli.sets import FORMATS as CLI_FORMATS
    assert (set(typing.get_args(ScenarioName)) == set(methods.SCENARIOS)
            and typing.get_args(Format) == FORMATS == CLI_FORMATS)


UNITLESS = {"--seed", "--seeds", "--instance", "--unit-seed", "--trials", "--positions", "--power", "--thermal-degree",
            "--threshold-factor", "--evaluations", "--record"}  # --record: a store's record id
UNIT_SUFFIXES = ("-deg", "-s", "-hz", "-dps", "-dph", "-g", "-c", "-arcmin", "-mps2", "-per-g", "-per-dps", "minutes")
OLD_NAMES = {"--out-dir": "-o/--output", "--json": "-o/--output", "--sigma": "--acc-noise-g/--gyro-noise-dph",
             "--rates": "--rates-dps", "--heading-error-deg": "--heading-accuracy-deg"}  # accepted, never shown first


UNIT_WORDS = {"-per-dps": r"per deg/s", "-per-g": r"per g\b", "-deg": r"\bdeg\b", "-s": r"\bs\b", "-hz": r"\bHz\b",
              "-dps": r"deg/s", "-dph": r"deg/h", "-g": r"\bg\b", "-c": r"degC", "-arcmin": r"arcmin",
              "-mps2": r"m/s\^2"}  # how a help text names the unit its option's name carries
CLOSED_SETS = ("-unit", "--scenario", "--method", "--criterion", "--timestamps", "--table")  # values from a closed set


def _option_rules(name, p, first):
    """On one shown option: help present; the unit its name carries named in the help;
    a closed set of values a click.Choice; a default shown."""
    import re

    import click
    assert p.help and p.help.strip(), f"{name} {first}: no help"
    suffix = next((u for u in UNIT_WORDS if first.endswith(u)), None)
    if suffix and first not in UNITLESS:
        assert re.search(UNIT_WORDS[suffix], p.help), f"{name} {first}: its help does not name its unit"
    if first.endswith(CLOSED_SETS):
        assert isinstance(p.type, click.Choice), f"{name} {first}: a closed set of values, not a click.Choice"
    if not p.is_flag and not p.multiple and not p.required and p.default is not None:
        assert p.show_default, f"{name} {first}: its default {p.default!r} is not shown"


def test_one_command_grammar():
    """`simucal VERB INPUT... -o OUTPUT [options]`. Every command that writes takes -o/--output;
    a number carries its unit in its name (or is a count); one name per quantity (the old names are
    aliases at most); every --help renders and names only options the command has;
    every option's help, units, choices and defaults (_option_rules); a hidden option is an old name."""
    import re

    import click
    from click.testing import CliRunner

    from simucal.cli import main
    commands = {f"{name} {sub}" if sub else name: c for name, cmd in main.commands.items()
                for sub, c in (getattr(cmd, "commands", {}) or {"": cmd}).items()}  # a group's: each of its own
    for name, cmd in commands.items():
        out = CliRunner().invoke(main, [*name.split(), "--help"], terminal_width=200)
        assert out.exit_code == 0, (name, out.output)
        options = [p for p in cmd.params if isinstance(p, click.Option)]
        if name not in ("derive", "store add"):  # derive writes generated/ itself, store add into its --store
            assert any({"-o", "--output"} <= set(p.opts) for p in options), f"{name} has no -o/--output"
            assert "-o, --output" in out.output, name
        for p in options:
            first = next(o for o in p.opts if o.startswith("--"))
            if p.hidden:  # an old name, accepted and never shown, and its help says so
                assert p.help and p.help.startswith(("Deprecated", "The old name")), f"{name} {first}: hidden, not old"
                continue
            _option_rules(name, p, first)
            assert first not in OLD_NAMES, f"{name} {first}: named {OLD_NAMES[first]} everywhere else"
            number = isinstance(p.type, (click.types.FloatParamType, click.types.IntParamType)) or (
                type(p.type).__name__ == "Number")
            if number and not p.is_flag:
                assert first in UNITLESS or first.endswith(UNIT_SUFFIXES), f"{name} {first}: a number without its unit"
        text = " ".join(filter(None, [cmd.help] + [p.help for p in options]))
        for verb, opt in re.findall(r"(?:(\b[a-z][a-z-]*) )?(?<![\w-])(--[a-z][a-z0-9-]*)", text):
            other = main.commands.get(verb, cmd)  # "calibrate --method field": another command's option
            known = {o for p in other.params if isinstance(p, click.Option) for o in p.opts} | {"--help"}
            assert opt in known, f"{name} --help mentions {verb} {opt}, which {other.name} does not take"


def test_files_and_functions_stay_short():
    """No hand-written file over 450 lines, no function over 70 (generated/ is written by derive)."""
    long_files, long_functions = [], []
    for p in list(ROOT.rglob("*.py")) + list((ROOT.parent / "derive").rglob("*.py")):
        if "generated" in p.parts:
            continue
        text = p.read_text()
        if len(text.splitlines()) > 450:
            long_files.append(p.name)
        long_functions += [f"{p.name}:{n.name} ({n.end_lineno - n.lineno + 1})" for n in ast.walk(ast.parse(text))
                           if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef)) and n.end_lineno - n.lineno >= 70]
    assert not long_files and not long_functions, (long_files, long_functions)


def test_no_issue_numbers_in_code():
    """Comments and docstrings say why in words: an issue number means nothing to the next reader of the code."""
    import re
    repo = ROOT.parent
    cited = [f"{p.relative_to(repo)}:{i}" for folder in ("simucal", "derive", "tests", "benchmarks")
             for p in (repo / folder).rglob("*.py") for i, line in enumerate(p.read_text().splitlines(), 1)
             if re.search(r"\b[Ii]ssues? \d+", line)]
    assert not cited, cited


def test_a_sets_kind_is_told_once_and_its_entry_looked_up(monkeypatch):
    """diagnose, validate, noise and simulate ask methods.KINDS for what a kind of data does: outside
    data_kind only a refusal of a set without segments.csv (and io/, which reads it) tests for one, and a
    kind added as one entry is the one the commands then use."""
    import re

    import numpy as np

    from simucal import methods
    from simucal.fit.stillness import still_stretches
    from simucal.api import MeasurementSet
    refusals = {"kinds.py": 1, "field/drift.py": 1, "turntable/observations.py": 1,
                "api/__init__.py": 1}  # read_set's example shows a user the segments
    found = {p.relative_to(ROOT).as_posix(): len(re.findall(r"segments is (not )?None", p.read_text()))
             for p in ROOT.rglob("*.py") if "io" not in p.relative_to(ROOT).parts[:1]}
    assert {k: n for k, n in found.items() if n} == refusals
    assert set(methods.KINDS) == set(methods.DATA) >= {m.data for m in methods.METHODS.values()}
    rows = np.arange(5, 45)
    third = methods.Kind("third", "third", None, None, None, None, None, None,
                         lambda ms: ([rows], "the third kind's still rows"), False)
    monkeypatch.setitem(methods.KINDS, "third", third)
    monkeypatch.setattr(methods, "data_kind", lambda ms: "third")
    ms = MeasurementSet.from_arrays(np.tile([0.0, 0.0, 1.0], (50, 1)), None, acc_unit="g", gyro_unit="deg/h",
                                    rate_hz=10.0)
    stretches, dt, where = still_stretches(ms, "acc", methods.kind_of(ms))
    assert where == "the third kind's still rows" and len(stretches[0]) == len(rows) and abs(dt - 0.1) < 1e-12


# What the command line may import: the API, its own helpers, output safety, the refusals, the
# words it prints and the registry of names its help shows. CLI_NOT_YET held the commands whose logic was not yet
# the API's; it may only stay empty.
CLI_MAY_IMPORT = {"simucal.api", "simucal.api.diagnosing", "simucal.api.planning", "simucal.api.tools", "simucal.cli",
                  "simucal.cli.common", "simucal.io.outputs", "simucal.errors", "simucal.progress",
                  "simucal.report.console", "simucal.report.lot_html", "simucal.report.units", "simucal.api.validating",
                  "simucal.sweeps", "simucal.methods", "simucal.io.cache"}  # the registry's names in the help, read at
# start without numpy; the cache's check that no input lies in it, beside output safety (common.guard); what is
# printed in the unit system asked (--units), as the console prints it
CLI_NOT_YET: set[str] = set()


def _is_module(name: str) -> bool:
    import importlib.util
    try:
        return importlib.util.find_spec(name) is not None
    except ModuleNotFoundError:
        return False


def test_the_command_line_stands_on_the_api():
    """cli/ imports the API, its helpers and output safety; the commands' logic is the API's (import, apply,
    convert, lot, montecarlo, plan and a batch of sets moved there: simucal.import_recording, simucal.apply_set,
    simucal.convert, simucal.lot, simucal.montecarlo, simucal.plan, simucal.sequence_observability,
    simucal.calibrate_each). An import outside both lists fails,
    and so does one of CLI_NOT_YET that the command line no longer needs (the list shrinks as commands move)."""
    used = set()
    for p in (ROOT / "cli").glob("*.py"):
        for node in ast.walk(ast.parse(p.read_text())):  # `from simucal import api` is simucal.api
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("simucal"):
                subs = {f"{node.module}.{a.name}" for a in node.names}
                used |= {m for m in subs if _is_module(m)} or {node.module}
    used = {m for m in used if not m.startswith("simucal.cli")}  # its own modules
    assert not used - CLI_MAY_IMPORT - CLI_NOT_YET, sorted(used - CLI_MAY_IMPORT - CLI_NOT_YET)
    assert not CLI_NOT_YET - used, f"no longer imported by cli/, drop from CLI_NOT_YET: {sorted(CLI_NOT_YET - used)}"


def test_no_module_shares_its_name_with_a_public_function():
    """`from simucal import X` and `simucal.X` must be the API's X whatever was imported before: a module
    simucal/X.py (or simucal/api/X.py) would bind X on its package at import, over the function (the two
    namespaces the public names live in). Each verb has one home, in a module of another name
    (api/calibrating.py for calibrate); the check finds a clash where one is planted."""
    import inspect

    import simucal.api

    def clashes(public: set[str]) -> list[str]:
        return sorted(f"{folder.relative_to(ROOT.parent).as_posix()}/{n}" for folder in (ROOT, ROOT / "api")
                      for n in public if (folder / f"{n}.py").exists() or (folder / n / "__init__.py").exists())
    functions = {n for n in simucal.__all__ if inspect.isfunction(getattr(simucal.api, n, None))}
    assert {"calibrate", "validate", "diagnose", "noise", "lot"} <= functions
    assert not clashes(functions), clashes(functions)
    assert clashes(functions | {"methods", "tools"}) == ["simucal/api/tools", "simucal/methods"]  # planted
    for name in functions:  # whatever the import order: the face's name is the function, defined once
        assert getattr(simucal, name) is getattr(simucal.api, name)
        assert getattr(simucal, name).__module__.split(".")[:2] == ["simucal", "api"], name


def _twice(sources: dict[str, str]) -> dict[str, list[str]]:
    """The public class names defined in two or more of these modules ({module: source}), and every class that
    subclasses the set or the calibration (a second class of the same concept)."""
    homes: dict[str, list[str]] = {}
    for where, source in sources.items():
        for node in ast.parse(source).body:
            if isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
                homes.setdefault(node.name, []).append(where)
                bases = {ast.unparse(b).split(".")[-1] for b in node.bases}
                if bases & {"Calibration", "MeasurementSet"}:
                    homes.setdefault(f"{node.name}({', '.join(sorted(bases))})", []).extend([where, "a subclass"])
    return {name: found for name, found in homes.items() if len(found) > 1}


def test_one_class_per_concept(tmp_path):
    """The API's set and calibration are io's own classes, never a subclass re-wrapping them, and a public class
    name is defined in one module only (Candidate was three classes, Check two): a reader who meets a name meets
    one class. Every verb returns those very classes; a planted second class of either kind is found."""
    import simucal
    from simucal import io
    assert simucal.Calibration is io.calibration.Calibration and simucal.MeasurementSet is io.MeasurementSet
    ms = simucal.simulate(seed=1)
    cal = simucal.calibrate(ms)
    simucal.save(tmp_path / "cal.json", cal)
    assert {type(ms), type(simucal.apply_set(cal, ms))} == {io.MeasurementSet}  # the class itself, no subclass
    assert {type(cal), type(simucal.load(tmp_path / "cal.json"))} == {io.calibration.Calibration}
    with pytest.raises(AttributeError, match=r"simucal\.apply\(cal, x"):  # the method that moved names its call
        cal.apply(ms.raw("acc"))
    sources = {p.relative_to(ROOT).as_posix(): p.read_text() for p in ROOT.rglob("*.py")}
    assert _twice(sources) == {}
    planted = {"a.py": "class Entry:\n    pass\n", "b.py": "class Entry(tuple):\n    pass\n",
               "c.py": "class Cal(io.calibration.Calibration):\n    pass\n"}
    assert set(_twice(planted)) == {"Entry", "Cal(Calibration)"}


def _untyped(hint, seen: set, where: str) -> list[str]:
    """Where a public type holds a record with no keys: a bare dict, or dict[..., Any], at any depth of the
    dataclasses, NamedTuples and TypedDicts of simucal it reaches."""
    import dataclasses

    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if hint is dict or (origin is dict and (not args or args[-1] is typing.Any)):
        return [where]
    if isinstance(hint, type) and hint.__module__.startswith("simucal") and hint not in seen:
        seen.add(hint)
        if typing.is_typeddict(hint) or dataclasses.is_dataclass(hint) or hasattr(hint, "_fields"):
            hints = typing.get_type_hints(hint, localns=_HINT_NAMES)
            return [e for k, h in hints.items() for e in _untyped(h, seen, f"{hint.__name__}.{k}")]
        return []
    return [e for a in args if not isinstance(a, typing.ForwardRef) for e in _untyped(a, seen, where)]


_HINT_NAMES: dict = {}  # the names imported for type checkers only, given at run time


def test_no_public_type_holds_a_record_without_keys():
    """Every public name's type (a class's fields, a function's parameters and result), and every
    simucal class those reach, names its records' keys: no bare dict and no dict[str, Any] (a document as
    written is records.JSONObject, JSON by type). The check finds one where it is planted."""
    import inspect

    import simucal.api
    from simucal.io import records
    from simucal.api.demo_run import DemoRecord
    from simucal.fit.allan_noise import NoiseReport
    from simucal.handheld.static_detect import DetectSettings
    _HINT_NAMES.update(JSONValue=records.JSONValue, DetectSettings=DetectSettings, NoiseReport=NoiseReport,
                       DemoRecord=DemoRecord)
    seen: set = set()
    found = []
    for name in simucal.__all__:
        obj = getattr(simucal.api, name, None)
        if inspect.isfunction(obj):
            hints = typing.get_type_hints(obj, localns=_HINT_NAMES)
            found += [e for k, h in hints.items() for e in _untyped(h, seen, f"{name}({k})")]
        elif isinstance(obj, type):
            found += _untyped(obj, seen, name)
    assert not found, found
    assert _untyped(dict[str, typing.Any], set(), "planted") == ["planted"]
    assert _untyped(typing.Optional[list[dict]], set(), "planted") == ["planted"]


MAPS = {"dict", "Dict", "Mapping", "MutableMapping"}


def _name(n: ast.expr) -> str | None:
    """dict of `dict` and of `typing.Dict`."""
    return n.id if isinstance(n, ast.Name) else n.attr if isinstance(n, ast.Attribute) else None


def _bare(hint: ast.expr) -> bool:
    """hint holds, at any depth, a dict whose keys no type names: a bare dict, or a mapping to Any or object."""
    if isinstance(hint, ast.Constant) and isinstance(hint.value, str):  # a quoted annotation
        return _bare(ast.parse(hint.value, mode="eval").body)
    keyed = {id(n.value) for n in ast.walk(hint) if isinstance(n, ast.Subscript)}
    for n in ast.walk(hint):
        if _name(n) in MAPS and id(n) not in keyed:
            return True
        if isinstance(n, ast.Subscript) and _name(n.value) in MAPS:
            last = n.slice.elts[-1] if isinstance(n.slice, ast.Tuple) else n.slice
            if _name(last) in ("Any", "object"):
                return True
    return False


def _bare_dict_returns(source: str, where: str) -> list[str]:
    """The public functions and methods of `source` that return a dict whose keys no type names (_bare, at
    any depth of the annotation: list[dict], tuple[X, dict[str, Any]]), or, unannotated, a dict display."""
    def a_dict(e: ast.expr | None) -> bool:  # a display, a comprehension or a call of dict
        return isinstance(e, (ast.Dict, ast.DictComp)) or (isinstance(e, ast.Call) and _name(e.func) == "dict")

    def returns_a_dict(f: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:  # unannotated: what it returns
        inner = {id(n) for g in ast.walk(f) if g is not f and isinstance(g, (ast.FunctionDef, ast.Lambda))
                 for n in ast.walk(g)}
        mine = [n for n in ast.walk(f) if id(n) not in inner]
        dicts = {t.id for n in mine if isinstance(n, (ast.Assign, ast.AnnAssign)) and a_dict(n.value)
                 for t in (n.targets if isinstance(n, ast.Assign) else [n.target]) if isinstance(t, ast.Name)}
        return any(isinstance(n, ast.Return) and (a_dict(n.value) or isinstance(n.value, ast.Name)
                                                  and n.value.id in dicts) for n in mine)
    return [f"{where}:{f.lineno} {f.name}" for f in ast.walk(ast.parse(source))
            if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef)) and not f.name.startswith("_")
            and (_bare(f.returns) if f.returns is not None else returns_a_dict(f))]


def test_no_public_function_returns_a_bare_dict():
    """Every public function and method of simucal/ that returns a dict, alone or in a list or tuple, says what
    it holds (a TypedDict, a parameterised mapping, records.JSONObject for a free-form document): no bare dict,
    no dict[str, Any]. The check finds each form where it is planted."""
    found = [e for p in sorted(ROOT.rglob("*.py")) if "generated" not in p.relative_to(ROOT).parts
             for e in _bare_dict_returns(p.read_text(), str(p.relative_to(ROOT)))]
    assert not found, found
    planted = ("def a() -> dict:\n    return {}\n"
               "def b(x) -> dict[str, Any] | None:\n    return None\n"
               "class C:\n    def c(self):\n        return {'k': 1}\n"
               "def d():\n    f = lambda: {}\n    return [f]\n"
               "def e() -> dict[str, float]:\n    return {}\n"
               "def _f() -> dict:\n    return {}\n"
               "def g() -> tuple[list[dict], int]:\n    return [], 0\n"
               "async def h() -> 'Mapping[str, Any]':\n    return {}\n"
               "def i() -> list[dict[str, list[float]]]:\n    return []\n"
               "def j() -> Optional[typing.Dict[str, typing.Any]]:\n    return None\n"
               "def k():\n    out = {}\n    out['x'] = 1\n    return out\n"
               "def m():\n    return dict(x=1)\n"
               "def n() -> Mapping:\n    return {}\n")
    assert sorted(e.split()[1] for e in _bare_dict_returns(planted, "planted")) == ["a", "b", "c", "g", "h", "j", "k",
                                                                                    "m", "n"]
