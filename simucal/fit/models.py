"""Load a generated error model and evaluate it: compiled CasADi C when a C
compiler is found, else the SymPy-printed numpy module (same derivation)."""
from __future__ import annotations

import importlib
import json
from pathlib import Path
from typing import TypedDict

import numpy as np

from simucal.fit.aux_inputs import AuxInputs
from simucal.io.cache import compile_c


class StaleGeneratedCode(RuntimeError):
    pass


class ManifestEntry(TypedDict):
    """One built-in model in generated/manifest.json (derive/codegen.py)."""
    c_file: str                       # its CasADi C source in generated/
    module: str                       # its SymPy-printed numpy module in generated/
    sha256: str                       # the derivation's hash, the module's MODEL_SHA256
    params: list[str]                 # its parameters, in order
    sensor: str                       # acc or gyro
    extends: str | None               # the model it adds terms to
    derivation: list[str]             # how each part was derived, in words


class Manifest(TypedDict):
    """generated/manifest.json: the built-in models and the versions that generated them."""
    format: str                       # simucal.generated/1
    models: dict[str, ManifestEntry]  # each built-in model by name
    versions: dict[str, str]          # SymPy's and CasADi's


def generated_dir() -> Path:
    import simucal.generated
    return Path(simucal.generated.__file__).parent


def manifest() -> Manifest:
    return json.loads((generated_dir() / "manifest.json").read_text())


def _bind_fit(lib, name):
    """The compiled whole-fit entry point of a model's library, through ctypes."""
    import ctypes
    f = getattr(ctypes.CDLL(str(lib)), f"simucal_{name}_fit")
    d = np.ctypeslib.ndpointer(dtype=float, flags="C_CONTIGUOUS")
    i = np.ctypeslib.ndpointer(dtype=np.intc, flags="C_CONTIGUOUS")
    v = ctypes.c_void_p  # p0, cov, cost: an address or None (start from the paper's linear fit; not wanted)
    f.argtypes = [ctypes.c_int, ctypes.c_int, d, d, d, d, v, ctypes.c_int, ctypes.c_double, d, v, d, v, i, i,
                  ctypes.c_int]
    f.restype = ctypes.c_int
    return f


class GeneratedModel:
    """An error model from generated/ (or a user's model from the cache): N(u, p), its
    Jacobians, the norm regression. `module` is the generated numpy module, `c_source`
    the CasADi C of the same derivation."""

    def __init__(self, name: str, module, c_source: str | None, compiled: bool = True):
        self.module = module
        self.name, self.sensor, self.unit = name, self.module.SENSOR, self.module.UNIT
        self.params = self.module.PARAMS
        self.param_units = self.module.PARAM_UNITS
        self.meanings = getattr(self.module, "MEANINGS", ("",) * len(self.params))
        self.source = getattr(self.module, "SOURCE", "built-in")
        self.aux = self.module.AUX
        self._lib = self._fit = None
        if compiled and c_source is not None:
            self._lib = compile_c(name, c_source)
            if self._lib is not None:
                self._fit = _bind_fit(self._lib, name) if f"simucal_{name}_fit" in c_source else None

    @property
    def backend(self) -> str:
        return "casadi-c" if self._lib is not None else "numpy"

    def aux_array(self, aux: AuxInputs | None, shape=None) -> np.ndarray:
        """The auxiliary inputs in this model's order (AUX), (*shape, naux), as its functions take them.
        None: the nominal point, every input 0 (M and the bias a calibration file reports)."""
        if aux is None:
            return np.zeros(tuple(shape or ()) + (len(self.aux),))
        return aux.array(self.aux, shape)

    def fit_compiled(self, N, rho, sig, aux, p0=None, max_iter=200, tol=1e-12, covariance=True, threads=0):
        """The whole exact fit in one compiled call (derive/templates/exact_fit.c) for a batch of
        data sets: N, sig (S, n, 3), rho (S, n), aux (S, n, naux), p0 (S, m) or None (each set
        starts from the paper's linear fit, computed in the same call). threads: the OpenMP team
        (0 its default; 1 where the caller runs batches on threads of its own). Returns p (S, m),
        cov (S, m, m), u (S, n, 3), cost (S,), iterations (S,), status (S,), with cov and cost None
        where covariance=False (the estimates alone); None without a compiler."""
        if self._fit is None:
            return None
        S, n, _ = N.shape
        m = len(self.params)
        c = lambda a: np.ascontiguousarray(a, dtype=float)
        N, rho, sig, aux = c(N), c(rho), c(sig), c(aux)
        p0 = None if p0 is None else c(p0)
        p, u = np.empty((S, m)), np.empty((S, n, 3))
        cov, cost = (np.empty((S, m, m)), np.empty(S)) if covariance else (None, None)
        iters, status = np.empty(S, np.intc), np.empty(S, np.intc)
        address = lambda a: None if a is None else a.ctypes.data
        self._fit(S, n, N, rho, sig, aux, address(p0), max_iter, tol, p, address(cov), u, address(cost), iters, status,
                  threads)
        return p, cov, u, cost, iters, status

    def output(self, u, p, aux: AuxInputs | None = None):
        u, p = np.asarray(u, float), np.asarray(p, float)
        if p.ndim > 1 and u.ndim > 2:  # a batch: one p per set
            p = p[..., None, :]
        return self.module.output(u, p, self.aux_array(aux, u.shape[:-1]))

    def jacobians(self, u, p, aux: AuxInputs | None = None):
        """N, dN/du (n,3,3), dN/dp (n,3,m) for rows u (n,3) and one p (m,); or for a batch of sets,
        u (S, n, 3) and p (S, m) (the numpy module, vectorised over the sets)."""
        u, p = np.asarray(u, float), np.asarray(p, float)
        A = self.aux_array(aux, u.shape[:-1])
        if p.ndim > 1:  # one p per set: broadcast it over the set's rows
            p = p[..., None, :]
        # the generated numpy module at any size: 2.5x faster than CasADi's per-row function at 12 rows,
        # 9x at 174 (its DM results' conversion), and no import of CasADi (0.1-0.3 s a command)
        N = self.module.output(u, p, A)
        Ju, Jp = self.module.output_jacobians(u, p, A)
        return N, Ju, Jp

    def norm_regressors(self, N, aux: AuxInputs | None = None):
        N = np.asarray(N, float)
        return self.module.norm_regressors(N, self.aux_array(aux, N.shape[:-1]))

    def params_of_K(self, K, first_order=False):
        f = self.module.params_of_K_first_order if first_order else self.module.params_of_K
        return f(K)

    def matrix_and_bias(self, p, aux: AuxInputs | None = None):
        """M and the bias (the model at u = 0), per row where the auxiliary inputs vary."""
        return self.module.matrix_and_bias(p, self.aux_array(aux))


def load_builtin(name: str, compiled: bool = True) -> GeneratedModel | None:
    """A built-in model from generated/, checked against its manifest entry; None if no such model."""
    entry = manifest()["models"].get(name)
    if entry is None:
        return None
    module = importlib.import_module(f"simucal.generated.{name}")
    if module.MODEL_SHA256 != entry["sha256"]:
        raise StaleGeneratedCode(f"generated/{name}.py does not match manifest.json; run `simucal derive`")
    return GeneratedModel(name, module, (generated_dir() / entry["c_file"]).read_text(), compiled)
