"""A new auxiliary input end to end: a supply_v column that a user's bias term
reads. Only the user's model file names it: the reader keeps the column, derive generates
the model with it, calibrate, diagnose and apply carry it by name."""
import json

import numpy as np
import pytest
from click.testing import CliRunner

from simucal import io
from simucal.cli import main
from simucal.fit.aux_inputs import AuxInputs

MODEL = '''
from simucal.derive.frames import column_input
from simucal.derive.models import Term
from simucal.derive.models.baseline import ACC_BASELINE

supply_v = column_input("supply_v", "V", "supply voltage")
MODELS = [ACC_BASELINE.with_terms("acc_supply_test", [
    Term("bV_z", "z", supply_v, "g/V", "z accelerometer bias changing with the supply voltage")])]
'''
TRUE_BV_Z = 2e-4  # g/V


def _run(*args):
    res = CliRunner().invoke(main, [str(a) for a in args])
    return res.exit_code, res.output


@pytest.mark.slow
def test_supply_voltage_term_simulated_found_calibrated_and_applied(tmp_path):
    model = tmp_path / "supply.py"
    model.write_text(MODEL)
    data = tmp_path / "set"
    code, out = _run("simulate", data, "--plan", "fibonacci48", "--effect-file", model, "--set", f"bV_z={TRUE_BV_Z}",
                     "--column", "supply_v=4.5:5.5", "--seed", 2)
    assert code == 0, out
    ms = io.read_set(data)
    assert np.ptp(ms.samples["supply_v"]) > 0.5  # the reader keeps the column

    code, out = _run("calibrate", data, "-o", tmp_path / "base.json")  # the baseline lacks the term
    assert code == 0 and "THE MODEL FAILS" in out

    code, out = _run("diagnose", data, "-o", tmp_path / "d.json")  # found beyond the library, by name
    assert code == 0 and "supply_v" in out
    shape = json.loads((tmp_path / "d.json").read_text())["acc"]["shape"]
    assert shape["regressor"] == "supply_v" and shape["axis"] == "z"
    found = tmp_path / "d_acc_model.py"
    assert found.is_file()

    for add in (model, found):  # the user's own file and the one diagnose wrote
        code, out = _run("calibrate", data, "--add", add, "-o", tmp_path / "cal.json")
        assert code == 0, out
        acc = json.loads((tmp_path / "cal.json").read_text())["acc"]
        name = [k for k in acc["params"] if k not in ("dK_x", "dK_y", "dK_z", "theta_yx", "theta_zx", "theta_zy",
                                                      "b_x", "b_y", "b_z")][0]
        assert abs(acc["params"][name] - TRUE_BV_Z) < 3 * acc["std"][name]
        assert acc["p_value"] > 1e-3
        # the user's term is listed under effects like a library one, named by its model
        assert acc["effects"][name]["value"] == acc["params"][name] and acc["effects"][name]["term_of"] == acc["model"]
        assert name in out  # and printed with its std
    code, out = _run("apply", tmp_path / "cal.json", data, "-o", tmp_path / "applied")
    assert code == 0, out
    applied = io.read_set(tmp_path / "applied")
    assert np.array_equal(applied.samples["supply_v"], ms.samples["supply_v"])  # carried through

    # the same model on data without the column: refused, naming it
    plain = tmp_path / "plain"
    assert _run("simulate", plain, "--plan", "fibonacci48")[0] == 0
    code, out = _run("calibrate", plain, "--add", model, "-o", tmp_path / "x.json")
    assert code != 0 and "supply_v" in out and not (tmp_path / "x.json").exists()


def test_reader_keeps_numeric_extra_columns_and_ignores_others(tmp_path):
    folder = tmp_path / "s"
    io.write_set(folder, {"acc_unit": "g", "gyro_unit": "deg/h", "latitude_deg": 45.0},
             {"t_s": np.arange(5.0), "ax": np.zeros(5), "ay": np.zeros(5), "az": np.ones(5),
              "supply_v": np.linspace(4.9, 5.1, 5)})
    text = (folder / "samples.csv").read_text().splitlines()
    text = [text[0] + ",note"] + [row + (",ok" if i else ",a b") for i, row in enumerate(text[1:])]
    (folder / "samples.csv").write_text("\n".join(text) + "\n")
    ms = io.read_set(folder)
    assert np.allclose(ms.samples["supply_v"], np.linspace(4.9, 5.1, 5))
    assert "note" not in ms.samples


def test_aux_inputs_order_defaults_and_refusal():
    aux = AuxInputs({"t_s": np.arange(3.0), "supply_v": 5.0})
    A = aux.array(("temp_c", "t_s", "supply_v"))
    assert A.shape == (3, 3) and np.all(A[:, 0] == 0) and np.all(A[:, 2] == 5.0)
    assert np.array_equal(aux.take([2]).array(("t_s",)), [[2.0]])
    try:
        aux.array(("t_s", "pressure_hpa"))
    except Exception as e:
        assert "pressure_hpa" in str(e)
    else:
        raise AssertionError("a column the data lack must be refused")
