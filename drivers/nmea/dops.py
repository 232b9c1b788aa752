"""Dilutions of precision of a geometry of satellites, as gpsd's ``fill_dop`` computes them.

The DOPs are the square roots of the diagonal of the inverse of the normal matrix
``sum(g g^T)`` of the rows ``g = (east, north, up, 1)`` of the unit vectors to the
satellites used; gpsd inverts it by Gauss-Jordan elimination with partial pivoting on
the matrix beside the identity (4 rows of 8). So does :func:`geometry_dops`, with the
same floating-point operations in the same order, so the results agree to the last bit
(tests/test_nmea_exact.py checks it against the plain loops on 3,000 geometries,
singular and nearly singular ones too).

The elimination is written out (:func:`_eliminator` generates it once, as
``msgs.construct`` writes out constructors): each step's pivot row is divided by the
pivot and subtracted from the other rows, on tuples that drop the column just
eliminated (after its step a column holds 0 or 1 and is never read again, nor are the
columns before it, so only the entries read later are computed). Written out, the
elimination costs about a third of the loops over lists it replaces.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any


def _eliminator() -> Callable[..., tuple[float, float, float, float] | None]:
    """``eliminate(r0, r1, r2, r3)``: Gauss-Jordan with partial pivoting (the first row of
    the largest magnitude, none below 1e-12: None, singular) on four rows of 8, the
    diagonal of the right half at the end."""
    src = ["def eliminate(r0, r1, r2, r3):"]
    for c in range(4):
        width = 8 - c  # the entries of each row at this step (its columns c..7)
        src.append(f"    p, best = {c}, abs(r{c}[0])")
        for r in range(c + 1, 4):
            src += [f"    v = abs(r{r}[0])", "    if v > best:", f"        p, best = {r}, v"]
        src += ["    if best < 1e-12:", "        return None"]
        for r in range(c + 1, 4):
            src += [f"    if p == {r}:", f"        r{c}, r{r} = r{r}, r{c}"]
        src.append(f"    piv = r{c}[0]")
        src.append(f"    r{c} = ({', '.join(f'r{c}[{j}] / piv' for j in range(1, width))},)")
        for r in range(4):
            if r != c:
                new = ", ".join(f"r{r}[{j}] - k * r{c}[{j - 1}]" for j in range(1, width))
                src += [f"    k = r{r}[0]", f"    r{r} = ({new},) if k != 0.0 else r{r}[1:]"]
    src.append("    return r0[0], r1[1], r2[2], r3[3]")
    env: dict[str, Any] = {}
    exec("\n".join(src) + "\n", env)
    return env["eliminate"]


_eliminate = _eliminator()


def geometry_dops(az_el: tuple[tuple[float, float], ...]) -> tuple[tuple[str, float], ...]:
    """The DOPs of satellites at these azimuths and elevations (degrees), each as (name,
    value), those a singular geometry (or fewer than 4 satellites) leaves out omitted.
    The matrix's sums run in the satellites' order (it is symmetric: 10 of them)."""
    if len(az_el) < 4:
        return ()
    xx = xy = xz = xw = yy = yz = yw = zz = zw = ww = 0.0
    for az, el in az_el:
        a, e = math.radians(az), math.radians(el)
        ce = math.cos(e)
        x, y, z = math.sin(a) * ce, math.cos(a) * ce, math.sin(e)
        xx += x * x
        xy += x * y
        xz += x * z
        xw += x
        yy += y * y
        yz += y * z
        yw += y
        zz += z * z
        zw += z
        ww += 1.0
    d = _eliminate(
        (xx, xy, xz, xw, 1.0, 0.0, 0.0, 0.0),
        (xy, yy, yz, yw, 0.0, 1.0, 0.0, 0.0),
        (xz, yz, zz, zw, 0.0, 0.0, 1.0, 0.0),
        (xw, yw, zw, ww, 0.0, 0.0, 0.0, 1.0),
    )
    if d is None:
        return ()
    d0, d1, d2, d3 = d
    computed = (("xdop", d0), ("ydop", d1), ("hdop", d0 + d1), ("vdop", d2),
                ("pdop", d0 + d1 + d2), ("tdop", d3), ("gdop", d0 + d1 + d2 + d3))  # fmt: skip
    return tuple((name, math.sqrt(v)) for name, v in computed if v >= 0.0)
