"""The suite's own scheduling: under ``make test`` (``pytest -n 2 --dist loadgroup``) the tests that share a
module-scoped fixture go to one worker, so that an expensive fixture (a trained run) is made once."""

import pytest


@pytest.fixture(scope="module")
def shared() -> list[str]:
    return []


def test_a_test_with_a_module_fixture_carries_its_group(request, shared):
    (mark,) = request.node.iter_markers("xdist_group")
    assert mark.args == ("test_suite_grouping::shared",)
    if request.config.getoption("dist", "no") == "loadgroup":
        # pytest-xdist sends a test to its group's worker by the group's name in the test's id; with a pytest whose
        # ids it cannot rename (9.2), the groups were silently ignored
        assert request.node.nodeid.endswith("@test_suite_grouping::shared"), request.node.nodeid


def test_a_test_without_one_carries_none(request):
    assert not list(request.node.iter_markers("xdist_group"))
