"""Hypothesis strategies of rotation vectors for the SO(3) tests.

Angles come from three regimes with equal weight: near the identity [0, 1e-6], anywhere
[0, pi], and near a half turn [pi - 1e-6, pi], about uniformly random axes.
"""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st

_component = st.floats(-1.0, 1.0, allow_nan=False)

unit_axes = st.tuples(_component, _component, _component).filter(
    lambda v: float(np.linalg.norm(v)) > 1e-3).map(lambda v: np.array(v) / np.linalg.norm(v))

angles = st.one_of(st.floats(0.0, 1e-6), st.floats(0.0, np.pi), st.floats(np.pi - 1e-6, np.pi))

#: Rotation vectors [rad] with norms in the three regimes above.
rotation_vectors = st.builds(lambda axis, angle: axis * angle, unit_axes, angles)

#: Rotation vectors away from pi (norm at most pi - 1e-3), for finite differences that must not
#: cross the half turn where the logarithm jumps.
rotation_vectors_below_pi = st.builds(
    lambda axis, angle: axis * angle, unit_axes,
    st.one_of(st.floats(0.0, 1e-6), st.floats(0.0, np.pi - 1e-3),
              st.floats(np.pi - 1e-2, np.pi - 1e-3)))
