"""Sensor error models as data.

A model is a list of named terms. Each term adds ``parameter * regressor`` to
one output axis, the regressor being any SymPy expression in the model's
inputs (f_x, f_y, f_z in g for accelerometers; w_x, w_y, w_z in deg/h for
gyros) and the auxiliary inputs of frames.AUX_INPUTS: temp_c and t_s, for gyros
the specific force f_x, f_y, f_z in g (g-sensitivity), for accelerometers the
centripetal scale w2 = w_T^2 / g under outer-axis rate (lever arms); and any
samples.csv column a user names (frames.column_input, e.g. supply_v). The output is

    N = u + sum_j p_j * regressor_j(u, aux) * e_axis(j)

with u the input in the sensor's parameter frame. dong2018 eq. 5 and 9 are the
baseline lists in ``baseline.py``; adding an effect is adding a Term.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass, field

import sympy as sp

from ..frames import AUX_INPUTS, AXES, RESERVED, SENSOR_AUX, f_b, omega_d

INPUTS = {"acc": f_b, "gyro": omega_d}
OUTPUT_UNIT = {"acc": "g", "gyro": "deg/h"}


@dataclass(frozen=True)
class Term:
    """One error term: ``name * regressor`` added to output ``axis``."""

    name: str
    axis: str
    regressor: sp.Expr
    unit: str
    meaning: str

    def __post_init__(self):
        if self.axis not in AXES:
            raise ValueError(f"term {self.name}: axis must be one of {AXES}, got {self.axis!r}")
        if not self.name.isidentifier():
            raise ValueError(f"term name {self.name!r} must be a Python identifier")
        object.__setattr__(self, "regressor", sp.sympify(self.regressor))
        if self.regressor.has(sp.nan, sp.zoo, sp.oo, -sp.oo):
            raise ValueError(f"term {self.name}: the regressor {self.regressor} is not finite (nan or infinity); "
                             "write a finite expression of the inputs")

    @property
    def symbol(self) -> sp.Symbol:
        return sp.Symbol(self.name, real=True)


@dataclass(frozen=True)
class ErrorModel:
    name: str
    sensor: str  # "acc" or "gyro"
    terms: tuple[Term, ...]
    description: str = ""
    extends: str | None = field(default=None)

    def __post_init__(self):
        if not self.name.isidentifier():  # it names files and C symbols
            raise ValueError(f"model name {self.name!r} must be a Python identifier (letters, digits, _), e.g. acc_mine")
        if self.sensor not in INPUTS:
            raise ValueError(f"model {self.name}: sensor must be 'acc' or 'gyro'")
        names = [t.name for t in self.terms]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise ValueError(f"model {self.name}: duplicate term names {sorted(dup)}")
        known = set(self.inputs) | set(self.params)
        for t in self.terms:
            for s in t.regressor.free_symbols - known:
                name = str(s)
                if name in SENSOR_AUX[self.sensor]:
                    continue
                if name in RESERVED or name in AUX_INPUTS:
                    raise ValueError(
                        f"model {self.name}, term {t.name}: {name} is not an input of {self.sensor} terms; they may "
                        f"use {sorted(map(str, self.inputs))}, {list(SENSOR_AUX[self.sensor])}, their parameters "
                        "and samples.csv columns (frames.column_input)")
                if not name.isidentifier():
                    raise ValueError(f"model {self.name}, term {t.name}: symbol {name!r} cannot name a samples.csv "
                                     "column; use an identifier (frames.column_input)")

    @property
    def inputs(self) -> tuple[sp.Symbol, ...]:
        return tuple(INPUTS[self.sensor])

    @property
    def aux(self) -> tuple[sp.Symbol, ...]:
        """Auxiliary inputs its terms read, in the order the generated functions take them: the sensor's
        built-in ones (frames.SENSOR_AUX) in their order, then the samples.csv columns, sorted. Only those
        read: every row's inputs are built and compared in the compiled fit (a baseline reads none)."""
        used = set().union(*(t.regressor.free_symbols for t in self.terms)) if self.terms else set()
        every = tuple(AUX_INPUTS[n].symbol for n in SENSOR_AUX[self.sensor])
        builtin = tuple(s for s in every if s in used)
        columns = used - set(self.inputs) - set(self.params) - set(every)
        return builtin + tuple(sorted(columns, key=str))

    @property
    def params(self) -> tuple[sp.Symbol, ...]:
        return tuple(t.symbol for t in self.terms)

    @property
    def unit(self) -> str:
        return OUTPUT_UNIT[self.sensor]

    def output(self) -> sp.Matrix:
        """N(u, p): the forward model, exact (no term neglected)."""
        out = sp.Matrix(self.inputs)
        for t in self.terms:
            out[AXES.index(t.axis)] += t.symbol * t.regressor
        return out

    def kind(self, term: Term) -> str:
        """'scale' (own-axis input), 'bias' (constant) or 'small' (everything else).

        Used by the first-order expansion of the norm: scale terms are kept
        exactly, as dong2018 keeps (1 + dK)^-2, the others to first order.
        """
        if term.regressor == self.inputs[AXES.index(term.axis)]:
            return "scale"
        if term.regressor.free_symbols == set():
            return "bias"
        return "small"

    def canonical(self) -> str:
        lines = [f"model {self.name} sensor {self.sensor}"]
        for t in self.terms:
            lines.append(f"{t.name}|{t.axis}|{sp.srepr(t.regressor)}|{t.unit}")
        return "\n".join(lines)

    def sha256(self) -> str:
        return hashlib.sha256(self.canonical().encode()).hexdigest()

    def with_terms(self, name: str, extra: list[Term], description: str = "") -> "ErrorModel":
        """This model plus extra terms, as a new model."""
        return ErrorModel(name, self.sensor, self.terms + tuple(extra),
                          description or f"{self.name} + " + ", ".join(t.name for t in extra),
                          extends=self.name)
