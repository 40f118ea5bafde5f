"""Checks shared by the objective tests: the analytic gradient against central differences."""

import numpy as np
import pytest


def value_grad_and_differences(obj, a, h=1e-6):
    """``obj.value_and_grad(a)`` (its value checked against ``obj(a)``) and central differences of ``obj`` at ``a``."""
    value, grad = obj.value_and_grad(a)
    assert value == pytest.approx(obj(a)[0], rel=1e-12)
    eye = np.eye(a.size)
    return value, grad, (obj(a + h * eye) - obj(a - h * eye)) / (2 * h)
