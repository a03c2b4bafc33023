"""A method's fit as a calibration file's block (sensor_block, affine_block), and its stds where they claim more
than the data hold: a parameter the plan cannot separate from the others (poorly_determined, listed) and a model
that fails its test (inflate_if_failing, every std scaled by the misfit)."""
from __future__ import annotations

import numpy as np

from simucal.io import records
from simucal.io.calibration import UNITS, EffectValue, SensorBlock
from simucal.io.details import as_details


def _user_terms(model, fit) -> dict:
    """A user's model file's terms beyond its sensor's baseline, as effects."""
    return {n: EffectValue(fit.params[n], fit.std[n], u, m, model.base.name)
            for n, u, m in zip(model.base.params, model.base.param_units, model.base.meanings)
            if n in model.model_file_terms}


def effect_values(model, fit) -> dict[str, EffectValue]:
    """The effects of `model` (an AugmentedModel: its library effects, and a model file's own terms) at `fit`."""
    effects = {e: EffectValue(fit.params[e], fit.std[e], u, m)
               for e, u, m in zip(model.effects, model.param_units[len(model.base.params):],
                                  model.meanings[len(model.base.params):])}
    effects.update(_user_terms(model, fit))
    return effects


def sensor_block(model, fit, M, bias, base: dict | None = None, C_b_model=None) -> SensorBlock:
    """The block of one sensor from a norm fit of `model` (an AugmentedModel); base: the model
    test's block (turntable/model_test.py)."""
    effects = effect_values(model, fit)
    block = SensorBlock(model.base.name, M, bias, model.unit, effects, model.base.source, dict(fit.params),
                        dict(fit.std), dict(zip(model.params, model.param_units)), C_b_model, fit.residual_rms,
                        model.unit, fit.chi2, fit.dof, fit.p_value)
    block.details["covariance"] = {"names": list(model.params), "matrix": np.asarray(fit.cov).tolist()}
    poor = poorly_determined(model.params, fit)
    if poor:
        block.details["poorly_determined"] = poor
    if base is not None:
        block.p_value = base["p_value"]
        block.details.update({"test": base["test"], "noise": base["noise"], "lack_of_fit": base["lack_of_fit"],
                              "cross_validation": base.get("cross_validation")})
        copied = {k: base[k] for k in ("rows", "noise_warning", "noise_too_small") if base.get(k)}
        copied |= {k: base[k] for k in ("omnibus_p_value", "omnibus_test", "targeted") if k in base}
        block.details.update(as_details(copied))
    return block


def affine_block(sensor: str, M, bias, std: dict, residual_rms: float | None, description: str,
                 residual_unit=None, effects=None, nominal=False, **details) -> SensorBlock:
    """The block of a method without a generated model: output = M u_b + bias (+ effects)."""
    unit = UNITS[sensor]
    return SensorBlock("affine", M, bias, unit, effects or {}, std=std, residual_rms=residual_rms,
                       residual_unit=residual_unit or unit, description=description, nominal=nominal,
                       chi2=details.pop("chi2", None), dof=details.pop("dof", None),
                       p_value=details.pop("p_value", None), details=as_details(details))


POOR_INFLATION = 10.0  # good plans give 1-2 (Table 1, fibonacci48, a hand-placed session)


def poorly_determined(names, fit) -> dict[str, records.Inflation]:
    """Parameters whose std the plan inflates more than POOR_INFLATION times by their correlation with
    the others: sqrt of the variance inflation factor, VIF_j = (R^-1)_jj for the correlation matrix R
    of the fit's covariance (1 for a parameter the plan separates from all others). A near-singular
    plan (gravity directions on one great circle) gives thousands. Parameters held by a prior are
    listed as undetermined instead."""
    cov = np.asarray(fit.cov, float)
    d = np.sqrt(np.diag(cov))
    if cov.shape != (len(names), len(names)) or not np.all(d > 0):
        return {}
    lam, V = np.linalg.eigh(cov / np.outer(d, d))
    inflation = np.sqrt((V ** 2 / np.maximum(lam, 1e-300)).sum(axis=1))
    return {n: {"std": float(fit.std[n]), "inflation": float(k)} for n, k in zip(names, inflation)
            if k > POOR_INFLATION and n not in fit.undetermined}


def inflate_if_failing(block: SensorBlock) -> bool:
    """When the model fails (p < ALPHA), scale every std by sqrt(chi2/dof), the misfit the
    noise does not explain, and keep the unscaled ones as std_raw. Returns whether it failed."""
    p, chi2, dof = block.p_value, block.chi2, block.dof
    if block.verdict != "fails":
        return False
    if chi2 is not None and dof:
        k = float(np.sqrt(chi2 / dof))
        if k > 1:
            block.details["std_raw"] = block.std
            block.std = {n: (np.asarray(v) * k).tolist() for n, v in block.std.items()}  # an affine block's lists too
            block.details["std_note"] = (f"the model fails (p = {p:.2g}); std = std_raw * sqrt(chi2/dof) = std_raw * "
                                         f"{k:.3g}, so it includes the misfit; std_raw assumes the model is right")
    return True
