"""Is the heading filter's variance telling the truth? Its NEES against the reference.

The heading filter (fusion.heading, ir-grid-mapping eq. 1-4) gives a heading and its
variance with every estimate; the IR map's cone (eq. 6) and the data association trust
that variance. Against a reference heading (the truth, or a data set's corrected poses),
the normalised estimation error squared NEES = e^2 / sigma^2 of a consistent filter
averages 1 and stays below chi-square(1) 99 % = 6.63 about 99 % of the time. The
heading is compared after aligning its first sample to the reference (it is dead
reckoning). Also reported: the final sigma and error, and whether the filter says its
heading is lost (3 sigma beyond 90 deg: the map drawn with it cannot be trusted).
"""

from __future__ import annotations

import math

import numpy as np

from hilnav.analysis.geometry import interp_pose
from hilnav.analysis.result import HeadingConsistency
from hilnav.analysis.tracks import Track
from numerics.angles import wrap

CHI2_1_99 = 6.634896601021214
LOST_3SIGMA_RAD = math.pi / 2


def heading_consistency(track: Track, ref: Track) -> HeadingConsistency | None:
    """NEES of a heading track with variances against a reference with headings."""
    if len(track.var) != len(track) or len(track) < 2 or len(ref) < 2:
        return None
    t = np.asarray(track.t, dtype=np.int64)
    order = np.argsort(t, kind="stable")
    t, th = t[order], np.asarray(track.theta)[order]
    var = np.asarray([v[2] for v in track.var], dtype=float)[order]
    rt, rx, ry, rth = ref.arrays()
    _, _, qth, ok = interp_pose(rt, rx, ry, rth, t)
    ok &= np.isfinite(var) & (var > 0) & np.isfinite(qth)
    if ok.sum() < 2:
        return None
    t, th, var, qth = t[ok], th[ok], var[ok], qth[ok]
    e = wrap(th - th[0] - (qth - qth[0]))
    nees = e * e / var
    sigma = np.sqrt(var)
    return HeadingConsistency(
        samples=int(len(e)),
        mean_nees=float(np.mean(nees)),
        within_99_fraction=float(np.mean(nees <= CHI2_1_99)),
        final_sigma_deg=float(np.degrees(sigma[-1])),
        final_error_deg=float(np.degrees(abs(e[-1]))),
        max_error_deg=float(np.degrees(np.max(np.abs(e)))),
        lost=bool(3.0 * sigma[-1] >= LOST_3SIGMA_RAD),
    )
