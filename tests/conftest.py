import pytest

from simucal.simulate import Scenario, write


@pytest.fixture(scope="session")
def paper_set(tmp_path_factory):
    """The paper scenario, one seed, shared by the calibration tests."""
    folder = tmp_path_factory.mktemp("paper")
    truth = write(folder, Scenario(), seed=3)
    return folder, truth
