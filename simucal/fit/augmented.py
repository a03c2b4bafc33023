"""A generated baseline model plus candidate effects from generated/effects.py.

N(u, p, q) = N_base(u, p, aux) + sum_k q_k * phi_k(u, aux) * e_axis(k)

Both halves are generated from derive/, so fitting baseline + candidate is
the exact solver on the derived model, with no re-derivation at run time.
"""
from __future__ import annotations

import functools
import hashlib
import os
import warnings
from pathlib import Path

import numpy as np

from simucal.errors import CalibrationError, InputError
from simucal.fit.aux_inputs import SENSOR_AUX, AuxInputs
from simucal.fit.catalog import derive_model_file, load
from simucal.fit.models import GeneratedModel
from simucal.generated.effects import EFFECTS


def effect_ids(sensor: str) -> list[str]:
    return [k for k, v in EFFECTS.items() if v.sensor == sensor]


def regressor(eid: str, u, aux: AuxInputs) -> np.ndarray:
    """Effect eid's regressor (generated/effects.py's phi) at inputs u (..., 3) and the auxiliary inputs
    aux, shaped u.shape[:-1] (a term constant in u broadcast): the one place its values are read."""
    effect, shape = EFFECTS[eid], np.shape(u)[:-1]
    return np.broadcast_to(effect.phi(u, aux.array(SENSOR_AUX[effect.sensor], shape))[0][..., 0], shape)


def effect_terms(effects, u, aux: AuxInputs | None):
    """Each effect's (axis, phi (u.shape[:-1]), dphi/du (..., 3)) at inputs u: what an effect adds to a
    model's output, p phi on its axis, and to its Jacobian in u (AugmentedModel, and apply's affine
    blocks). Built-in auxiliary inputs only, 0 where aux lacks them."""
    effects = tuple(effects)
    if not effects:
        return
    A = (aux or AuxInputs()).array(SENSOR_AUX[EFFECTS[effects[0]].sensor], np.shape(u)[:-1])
    for e in effects:
        phi, dphi = EFFECTS[e].phi(u, A)
        yield EFFECTS[e].axis, np.broadcast_to(phi[..., 0], np.shape(u)[:-1]), dphi


def for_sensor(ids, sensor: str) -> tuple[str, ...]:
    """The effect ids of one sensor (each library effect knows its own)."""
    return tuple(e for e in ids if EFFECTS[e].sensor == sensor)


def follows_temperature(eid: str) -> bool:
    """Whether a library effect's regressor reads the temperature (temp_c or dtemp_c)."""
    return bool({"temp_c", "dtemp_c"} & set(EFFECTS[eid].reads))


def check_effect(eid: str, sensor: str | None = None):
    """Refuse anything but an exact effect id, naming the ids that come closest."""
    if eid not in EFFECTS:
        import difflib
        low = {k.lower(): k for k in EFFECTS}
        near = ([low[eid.lower()]] if eid.lower() in low else
                [k for k in EFFECTS if eid and eid.lower() in k] or difflib.get_close_matches(eid, list(EFFECTS), 5))
        fam = sorted({".".join(k.split(".")[:2]) for k in EFFECTS})
        raise InputError(f"unknown effect {eid!r}" + (f"; did you mean {', '.join(near[:9])}?" if near else ".")
                       + f" Ids are <sensor>.<family>.<axis>, families {fam}, axes x, y, z (and pairs xy, ...). "
                       "A term of your own: a model file (--add my_model.py).")
    if sensor is not None and EFFECTS[eid].sensor != sensor:
        raise InputError(f"effect {eid} is for the {EFFECTS[eid].sensor}, not the {sensor}.")


class AugmentedModel:
    def __init__(self, base: GeneratedModel | str, effects=()):
        self.base = load(base) if isinstance(base, str) else base
        for e in effects:
            check_effect(e, self.base.sensor)
        self.effects = tuple(effects)
        self.sensor, self.unit = self.base.sensor, self.base.unit
        self.name = self.base.name + "".join(f"+{e}" for e in self.effects)
        self.params = tuple(self.base.params) + self.effects
        self.param_units = tuple(self.base.param_units) + tuple(EFFECTS[e].unit for e in self.effects)
        self.meanings = tuple(self.base.meanings) + tuple(EFFECTS[e].meaning for e in self.effects)
        self.aux = self.base.aux
        self._m = len(self.base.params)
        if self.effects and self.base.source != "built-in":
            self._check_no_term_twice()

    def _check_no_term_twice(self, rows=48):
        """Refuse a library effect that is one of the model file's own terms (their regressors agree at
        random inputs up to a factor): the fit cannot tell the two apart, and would blame the plan."""
        rng = np.random.default_rng(0)
        u = rng.normal(size=(rows, 3))
        u *= (1.0 if self.sensor == "acc" else 1e4) / np.linalg.norm(u, axis=1, keepdims=True)
        names = set(self.base.aux) | set(SENSOR_AUX[self.sensor])
        _, _, Jp = self.jacobians(u, np.zeros(len(self.params)), AuxInputs({n: rng.uniform(-1, 1, rows)
                                                                             for n in names}))
        cols = Jp.reshape(-1, Jp.shape[-1])
        cols = cols / np.maximum(np.linalg.norm(cols, axis=0), 1e-300)
        own = [self.params.index(n) for n in self.model_file_terms]
        for k, e in enumerate(self.effects, start=self._m):
            same = [self.params[i] for i in own if abs(cols[:, i] @ cols[:, k]) > 1 - 1e-9]
            if same:
                raise CalibrationError(
                    f"the library effect {e} and the term {same[0]} of model {self.base.name} (your model file) "
                    f"are the same term: no data can tell them apart; keep one (leave {e} out of --add/--effect, "
                    f"or {same[0]} out of the model file)")

    @property
    def model_file_terms(self) -> tuple[str, ...]:
        """The parameters a user's model file adds to its sensor's baseline (none for built-in models)."""
        if self.base.source == "built-in":
            return ()
        baseline = set(load(f"{self.sensor}_baseline").params)
        return tuple(n for n in self.base.params if n not in baseline)

    def _terms(self, u, aux: AuxInputs | None):
        return effect_terms(self.effects, u, aux)

    def output(self, u, p, aux: AuxInputs | None = None):
        p = np.asarray(p, float)
        N = self.base.output(u, p[..., :self._m], aux)
        if self.effects:
            N += self.effects_output(u, p, aux)
        return N

    def effects_output(self, u, p, aux: AuxInputs | None = None):
        """The effects' share of the output: each effect's q phi(u) along its axis."""
        p = np.asarray(p, float)
        E = np.zeros(np.shape(u))
        batch = p.ndim > 1 and np.ndim(u) > 2  # one p per set: its effects broadcast over the set's rows
        for q, (axis, phi, _) in zip(np.moveaxis(p[..., self._m:], -1, 0), self._terms(u, aux)):
            E[..., axis] += (q[..., None] if batch else q) * phi
        return E

    def jacobians(self, u, p, aux: AuxInputs | None = None):
        """As GeneratedModel.jacobians, rows (n, 3) with one p, or a batch u (S, n, 3), p (S, m)."""
        p = np.asarray(p, float)
        N, Ju, Jp = self.base.jacobians(u, p[..., :self._m], aux)
        cols = []
        for q, (axis, phi, dphi) in zip(np.moveaxis(p[..., self._m:], -1, 0), self._terms(u, aux)):
            q = np.asarray(q)[..., None] if p.ndim > 1 else q
            N[..., axis] += q * phi
            Ju[..., axis, :] += q[..., None] * dphi if np.ndim(q) else q * dphi
            col = np.zeros(np.shape(u))
            col[..., axis] = phi
            cols.append(col)
        if cols:
            Jp = np.concatenate([Jp, np.stack(cols, axis=-1)], axis=-1)
        return N, Ju, Jp

    def matrix_and_bias(self, p, aux: AuxInputs | None = None):
        return self.base.matrix_and_bias(np.asarray(p, float)[..., :self._m], aux)

    def norm_regressors(self, N, aux: AuxInputs | None = None):
        if self.effects:
            raise NotImplementedError("the linear norm regression exists for derived models only")
        return self.base.norm_regressors(N, aux)

    def params_of_K(self, K, first_order=False):
        return self.base.params_of_K(K, first_order)


def compiled_form(model: AugmentedModel) -> GeneratedModel | None:
    """The augmented model derived as one model (a built-in base with the effects' terms), so that
    its whole fit runs compiled, as the base's does: derived once, with SymPy in a child process,
    from a model file simucal writes into the cache (catalog.derive_model_file), then loaded from
    there. None without effects, for a user's base model, or without a compiler (the numpy fit of
    the AugmentedModel is then the same numbers). Its parameters are the base's and then one per
    effect, in the AugmentedModel's order (checked)."""
    from simucal.io.cache import compiler
    if not model.effects or model.base.source != "built-in" or compiler() is None:
        return None
    derived = _derived(model.base.name, model.effects)
    if derived is None or tuple(derived.params[:model._m]) != tuple(model.base.params) \
            or len(derived.params) != len(model.params):
        return None
    return derived if derived._fit is not None else None


@functools.lru_cache(maxsize=None)
def _derived(base: str, effects: tuple) -> GeneratedModel | None:
    """compiled_form's model, derived (or found in the cache) once per process; None (said once) where
    the cache cannot take it (read-only) or the derivation fails: the numpy fit gives the same numbers."""
    try:
        return _derive(base, effects)
    except (OSError, ValueError, KeyError) as e:
        warnings.warn(f"the compiled form of {base} + {', '.join(effects)} could not be derived into the cache "
                      f"({e}); its fits run in numpy")
        return None


def _derive(base: str, effects: tuple) -> GeneratedModel:
    """The model file is written by simucal here, into the user's own cache (UntrustedCache where
    that is not the user's alone), and written again wherever it holds other bytes: a model file is
    run when it is derived, and simucal runs only files it wrote or the user named."""
    from simucal.io.cache import own_folder
    name = "_with_".join([base] + [e.replace(".", "_") for e in effects])  # CasADi: no "__"
    if len(name) > 80:  # many effects: a file name the file system takes
        name = f"{base}_with_{hashlib.sha256(name.encode()).hexdigest()[:16]}"
    text = ("from simucal.derive.models.effects import CANDIDATES\n"
            "from simucal.derive.registry import BUILTIN\n"
            f"BASE = next(m for m in BUILTIN if m.name == {base!r})\n"
            f"MODELS = [BASE.with_terms({name!r}, [CANDIDATES[e] for e in {list(effects)!r}])]\n")
    path = own_folder("augmented") / f"{name}.py"
    if not path.is_file() or path.read_text() != text:
        from simucal.io import outputs
        outputs.write_text(path, text, mode=0o644)
    derive_model_file(path)
    return load(name)


def resolve_add(add, acc_model: str, gyro_model: str) -> tuple[str, str, tuple[str, ...]]:
    """What `--add` names: effect ids (checked; unknown ones refused) and model files
    (derived into the cache; each file's models replace the base model of their sensor).
    Returns (acc base model, gyro base model, effect ids)."""
    ids = []
    for a in add:
        if a.endswith(".py"):
            for name in derive_model_file(a)[0]:
                if load(name).sensor == "acc":
                    acc_model = name
                else:
                    gyro_model = name
        else:
            refuse_a_path(a)
            check_effect(a)
            ids.append(a)
    return acc_model, gyro_model, tuple(dict.fromkeys(ids))


def refuse_a_path(a: str) -> None:
    """Refuse a folder or a path given to --add, where an effect id or a model file goes (a measurement set put
    after --add instead of before it read as an unknown effect, every family listed)."""
    if a in EFFECTS or not (os.sep in a or "/" in a or Path(a).exists()):
        return
    if Path(a).is_dir():
        raise InputError(f"--add {a}: a folder (a measurement set?), not an effect id or a model file: a set goes as "
                         f"the command's argument, not after --add (SET --add EFFECT: {a} --add acc.quadratic.z)")
    what = "a file, not a model file (.py)" if Path(a).exists() else "a path, and no such file"
    raise InputError(f"--add {a}: {what}, where an effect id (acc.quadratic.z) or a model file (my_model.py) is "
                     "expected")
