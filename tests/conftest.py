import os
import tempfile

import pytest

# user models derived by the tests go to a cache of their own, never the user's
os.environ["SIMUCAL_CACHE"] = tempfile.mkdtemp(prefix="simucal-test-cache-")

from simucal.turntable.simulate import Scenario, write  # noqa: E402 (after the cache is set)


@pytest.fixture(scope="session")
def audit_report():
    """The paper's audit with the section-4 term-by-term check (SymPy, seconds): shared by its tests."""
    from simucal.derive.audit import run_audit
    from simucal.report.paper_claims import section4_values
    return run_audit(values=section4_values())


@pytest.fixture(scope="session")
def paper_set(tmp_path_factory):
    """The paper scenario, one seed, shared by the calibration tests."""
    folder = tmp_path_factory.mktemp("paper")
    truth = write(folder, Scenario(), seed=3)
    return folder, truth
