"""Pure numerics shared by every layer: angle wrapping, the differential-drive odometry
model of ekf-vs-cp eq. (1)-(2) with its Jacobians, and the EKF pieces of eq. (3)-(4).

Layer 0, below ``msgs``: functions of floats and arrays only, no message types, no I/O,
no state. It sits under ``msgs`` rather than between ``msgs`` and the algorithms because
``msgs`` re-exports the scalar :func:`numerics.angles.wrap_angle` as ``msgs.wrap_angle``
(one implementation, reachable from both names). ``import msgs`` stays free of numpy:
this ``__init__`` imports nothing and :mod:`numerics.angles` imports numpy only inside
its array function; :mod:`numerics.motion` and :mod:`numerics.ekf` use numpy and are
imported by the algorithm packages (fusion, mapping, localization) only.

- :mod:`numerics.angles`: wrap to (-pi, pi], scalar and array;
- :mod:`numerics.motion`: eq. (1) wheels <-> step, eq. (2) pose step, F and G Jacobians;
- :mod:`numerics.ekf`: eq. (4) covariance prediction, innovation, NIS, Joseph update;
- :mod:`numerics.rangebearing`: range and bearing of a point from a pose, Jacobians.
"""
