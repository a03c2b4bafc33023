"""The paper audit, completed: every printed row of eq. 17, 21, 25-27 term by term at the
section-4 values, the dropped norm constant, Table 2's rank, and the numeric claims by Monte Carlo."""
import math

import pytest

from simucal.report.paper_claims import claims

VERDICTS = ("agrees", "OCR damage", "error in the paper", "neglected", "claim not supported", "reproducible",
            "not reproducible")


@pytest.fixture(scope="module")
def terms(audit_report):
    return audit_report.terms


@pytest.mark.slow
def test_every_row_has_terms_sizes_and_a_verdict(terms):
    rows = {(t.eq, t.row) for t in terms}
    for eq, n in (("17", 3), ("21", 3), ("25-26", 5), ("27", 3), ("Table 2", 2)):
        assert sum(1 for e, _ in rows if e == eq) == n, (eq, rows)
    for t in terms:
        assert math.isfinite(t.size) and t.verdict.startswith(VERDICTS), t


def test_findings_of_substance_are_named_with_their_size(terms):
    by = {(t.eq, t.row, t.term): t for t in terms}
    # eq. 21 z row counts w_T cos(alpha) twice: 36000 deg/h at alpha = 0
    double = by[("21", "N_z^g", "w_T*cos(alpha)")]
    assert double.verdict.startswith("error in the paper") and abs(double.size - 36000) < 1
    # the horizontal Earth rate kept in eq. 21 averages out: w_e cos L = 10.6 deg/h
    earth = by[("21", "N_y^g", "w_e*cos(L)*cos(alpha)")]
    assert "averages out" in earth.verdict and abs(earth.size - 15.04107 * math.cos(math.radians(45))) < 1e-6
    # a neglected first-order term of the size of the gyro noise
    assert by[("21", "N_x^g", "lambda_z4*w_e*sin(L)*sin(alpha)")].verdict.startswith("neglected")
    # eq. 27's lambda_z4 reads the wrong position; eq. 25's third line the wrong sign
    lz = next(t for t in terms if t.eq == "27" and t.row == "lambda_z4")
    assert "position 1" in lz.verdict and lz.size > 1e-4
    # the scale-factor products in eq. 25: dK_y * theta_x4 = 0.008 * 12' = 2.8e-5 rad
    tx = next(t for t in terms if t.row.startswith("theta_x4"))
    assert "products dK * angle make 2.8e-05 rad" in tx.verdict
    const = next(t for t in terms if t.eq == "6-7")
    assert const.term.startswith("dropped constant") and 1e-6 < const.size < 1e-4
    assert all(t.verdict.startswith("agrees: sufficient") for t in terms if t.eq == "Table 2")


def test_claims_each_measured():
    rows = claims(seeds=4)
    assert {r["source"] for r in rows} >= {"abstract", "Table 3", "Table 4", "section 4"}
    assert sum(r["source"] == "Table 4" for r in rows) == 20  # every printed entry
    for r in rows:
        assert r["measured"] and r["holds"] in VERDICTS, r
    # the norm method's error does not grow with the table's position errors; the previous one's does
    grows = [r for r in rows if r["claim"].startswith("previous method") and "grows" in r["claim"]]
    assert grows and all(r["holds"] == "agrees" for r in grows)
