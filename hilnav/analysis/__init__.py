"""``hilnav analyze``: what a log allows to conclude (errors, drift, map, boxes) and its plots.

``analyze`` (the entry point: a typed ``result.Analysis`` per log), ``tracks`` (the log read
into per-robot tracks), ``geometry`` (interpolation, alignment, rigid fit), ``errors`` (path
and heading errors, drift per metre), ``containment`` (CP boxes, EKF 3-sigma), ``maps`` (map
quality), ``report`` (JSON summary, digest, report files), ``plots`` (PNGs).
"""
