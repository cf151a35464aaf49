"""Shared fixtures of the sensor tests: a bare PyBullet client."""

import pybullet as p
import pytest


@pytest.fixture
def client():
    c = p.connect(p.DIRECT)
    yield c
    p.disconnect(c)
