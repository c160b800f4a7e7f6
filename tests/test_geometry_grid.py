"""The cached arc-length grid the contour error seeds from."""

import numpy as np

import nurbsmotion as nm


def test_uniform_parameters_are_the_inverse_arc_length_of_an_even_grid():
    curve = nm.make_butterfly()
    g = curve.geometry
    u = g.uniform_parameters(101)
    np.testing.assert_array_equal(u, curve.parameter_at(np.linspace(0, curve.length, 101)))
    u[:] = 0.0  # a copy: the cache is not exposed
    np.testing.assert_allclose(np.diff(curve.arc_length(g.uniform_parameters(101))),
                               curve.length / 100, rtol=1e-9)
