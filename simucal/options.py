"""calibrate's options as one typed, frozen object, built once (by `simucal.calibrate`'s keywords or by the
command line's flags) and checked once: every method's function takes it whole (`Method.run(ms, options)`),
and reads the fields its entry in methods.py declares; an option set that the method does not read is
refused by one rule (`unused`), naming the flag and the methods that read it.

Each field carries its command-line flag, its unit and its words in one place (scikit-learn's habit of
explicit parameters checked in one place): calibrate's help, the API's docstring and the refusals read them.
"""
from __future__ import annotations

import os
import textwrap
import typing
from dataclasses import MISSING, dataclass, field, fields
from typing import TYPE_CHECKING, Any, Collection, Literal

if TYPE_CHECKING:
    from simucal.handheld.static_detect import DetectSettings

# "auto" and methods.NAMES (tests/test_architecture.py checks that they agree)
Method = Literal["auto", "exact", "linear", "multiposition", "ferraris", "handheld", "field", "systematic"]
Timestamps = Literal["auto", "recorded", "nominal"]
AUTO = "auto"  # in `add`: the forward selection of the library effects a failing model needs


def option(default: Any, flag: str | None, unit: str, words: str) -> Any:
    """A field of CalibrateOptions: its default, its flag (None: set by simucal itself, no keyword), its unit
    ("" where it has none) and what it is."""
    return field(default=default, metadata={"flag": flag, "unit": unit, "words": words})


@dataclass(frozen=True)
class CalibrateOptions:
    """What `simucal calibrate` takes beside the data (module doc); the defaults are the command's."""
    method: Method = option("auto", "--method", "", "the method: auto (the one the data's kind takes), exact, "
                            "linear, multiposition, ferraris, handheld, field or systematic")
    add: tuple[str, ...] = option((), "--add", "", "effect ids, model files, or 'auto' (a forward selection of the "
                                  "library effects a failing model needs); one as a string")
    acc_model: str = option("acc_baseline", "--acc-model", "", "the accelerometer model: a built-in's name or a "
                            "model file")
    gyro_model: str = option("gyro_baseline", "--gyro-model", "", "the gyro model: a built-in's name or a model file")
    acc_noise_g: float | None = option(None, "--acc-noise-g", "g", "the noise of one accelerometer row, where the "
                                       "data cannot give it")
    gyro_noise_dph: float | None = option(None, "--gyro-noise-dph", "deg/h", "the noise of one gyro row, where the "
                                          "data cannot give it")
    heading_accuracy_deg: float = option(5.0, "--heading-accuracy-deg", "deg", "a field set's north reference "
                                         "accuracy")
    t_ref_c: float | None = option(None, "--t-ref-c", "degC", "T_ref of the temperature terms (None: the data's "
                                   "mean temperature; over temperature, the plateaus')")
    noise: str | os.PathLike[str] | None = option(None, "--noise", "", "a noise.json of `simucal noise`: each "
                                                  "segment's noise from its Allan curve at the segment's length")
    detect: DetectSettings | None = option(None, "--init-rest-s, --threshold-factor, --window-s, --min-static-s and "
                                           "--gyro-limit-dps (a stream's)", "", "a stream's static detection (its "
                                           "window, threshold factor, shortest pose, initial rest, gyro limit)")
    timestamps: Timestamps = option("auto", "--timestamps", "", "a stream's clock: the recorded time stamps, the "
                                    "even clock of their median step (nominal), or auto")
    thermal: bool = option(False, "--thermal", "", "one set whose temperature ramps calibrated over temperature "
                           "(a list of sets always is)")
    thermal_degree: int | None = option(None, "--thermal-degree", "", "the thermal polynomials' degree, 0-3 (None: "
                                        "chosen per parameter by the data)")
    rank: bool = option(True, None, "", "a failing model's candidates ranked (a thermal fit's plateaus need none)")
    noise_curves: Any = option(None, None, "", "--noise's Allan curves, read once before any work")

    def __post_init__(self) -> None:
        if isinstance(self.add, str) or not isinstance(self.add, tuple):  # one id or model file, or a list
            object.__setattr__(self, "add", (self.add,) if isinstance(self.add, str) else tuple(self.add))
        if self.thermal_degree is not None:  # a degree is a thermal calibration's: never dropped
            object.__setattr__(self, "thermal", True)

    @property
    def effect_ids(self) -> tuple[str, ...]:
        """add without 'auto': effect ids and model files."""
        return tuple(a for a in self.add if a != AUTO)

    @property
    def auto(self) -> bool:
        """Whether add asks for the forward selection."""
        return AUTO in self.add


# What calibrate itself reads, whatever the method: the method's choice, the clock, T_ref, temperature.
EVERY_METHOD = frozenset({"method", "timestamps", "t_ref_c", "thermal", "thermal_degree", "rank", "noise_curves"})


def keywords() -> list[str]:
    """The options a caller gives by name: every field with a flag (rank and noise_curves are simucal's own)."""
    return [f.name for f in fields(CalibrateOptions) if f.metadata["flag"] is not None]


def given(options: CalibrateOptions) -> list[tuple[str, str]]:
    """(name, flag) of every option set away from its default; add's effects and its 'auto' apart, as a method
    may read one and not the other (names "add" and "add auto")."""
    out = []
    for f in fields(options):
        value = getattr(options, f.name)
        if f.name == "add":
            out += [("add", "--add")] * bool(options.effect_ids) + [("add auto", "--add auto")] * options.auto
        elif value != (f.default if f.default is not MISSING else None):
            out.append((f.name, f.metadata["flag"]))
    return out


def unused(options: CalibrateOptions, reads: Collection[str],
           own: Collection[str] = EVERY_METHOD) -> list[tuple[str, str]]:
    """(name, flag) of every option set that is neither read (`reads`: a method's declared fields) nor the
    caller's `own` (calibrate's, whatever the method): the one rule by which an option that would be ignored is
    refused."""
    return [(n, flag) for n, flag in given(options) if n not in reads and n not in own]


def described() -> str:
    """The options as numpydoc's parameter lines (calibrate's help()): name : type, default; what it is, its flag
    and its unit."""
    literals = {"Method": Method, "Timestamps": Timestamps}
    lines = []
    for f in fields(CalibrateOptions):
        if f.metadata["flag"] is None:
            continue
        kind = str(f.type).replace("os.PathLike[str]", "os.PathLike")
        if kind in literals:
            kind = "{" + ", ".join(map(repr, typing.get_args(literals[kind]))) + "}"
        words = f.metadata["words"][0].upper() + f.metadata["words"][1:] + f" ({f.metadata['flag']})."
        if f.metadata["unit"]:
            words += f" In {f.metadata['unit']}."
        lines += [f"{f.name} : {kind}, default {f.default!r}", textwrap.fill(words, 110, initial_indent="    ",
                                                                             subsequent_indent="    ")]
    return "\n".join(lines)
