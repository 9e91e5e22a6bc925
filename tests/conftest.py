import pytest

from tests.helpers import REFERENCE, Children


@pytest.fixture
def children():
    c = Children()
    try:
        yield c
    finally:
        c.stop_all()


@pytest.fixture
def reference():
    if not REFERENCE.is_dir():
        pytest.skip("../shared/reference is absent")
    return REFERENCE
