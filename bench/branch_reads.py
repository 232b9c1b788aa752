"""Diagnostic: how much of the drift branches' map work a lazily evaluated branch map
could skip (mapping.heading_drift; issue 18, sixth round).

The branch maps are read only where a scored scan's six rays run (``DriftBank.score``)
until a branch is adopted. A lazy map would apply a scan that came of age only when a
read needs it, and skip the rest. This runs the association with ``DriftBank`` hooked
(its results unchanged: the hooks only look) and counts, for every branch:

- scan level: an insertion is what one ``age`` call puts into one branch's map (the
  scans that came of age in a step). At each score, the pending insertions whose cells
  meet the cells the score's rays read: those and every earlier pending one must be
  applied (a cell's updates in order), the rest may wait. ``insertions_skippable`` is
  what still waits when the bank ends (its adopted branch: none);
- cell level: each branch cell update is "read" if a later score's rays read its cell
  before the bank ends, "adopted" if its branch is adopted first, else never needed.
  This bounds a per-cell lazy map (which must still find every scan's cells).

The cells are exact: each scan's cone cells recomputed at the branch's pose, and the
cells ``expected_ranges`` reads along every ray. Default: bench/grid_mapping.py's run;
``--ir-real DIR``, bench/ir_real.py's runs on a laser log (its own options after it);
``--replay LOG``, ``hilnav replay`` of a daemon log (the output to a temporary file).

    python bench/branch_reads.py [--seed 1] [--distance 70]
    python bench/branch_reads.py --ir-real /work/shared/data/intel --seeds 1 --scans 2500
    python bench/branch_reads.py --replay /tmp/lz-log/bench.mcap
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from mapping import heading_drift as hd
from mapping.grid import OccupancyGrid
from mapping.ir_inverse import IrInverseModel
from mapping.se2 import compose

SIDE = 4000  # world cells on a side of the counting box (200 m at 0.05 m)
COUNTS: Counter[str] = Counter()
MODEL = IrInverseModel(reuse_cells=0)  # recomputes the cells: the association's memo untouched


def world_keys(g: OccupancyGrid, flat: np.ndarray) -> np.ndarray:
    """Cells as indices into a fixed world box (the grid may grow between scans)."""
    r, c = np.divmod(flat, g.shape[1])
    r0 = round(g.origin[1] / g.resolution) + SIDE // 2
    c0 = round(g.origin[0] / g.resolution) + SIDE // 2
    return (r + r0) * SIDE + (c + c0)


class Tally:
    """One bank's counts: per branch, the pending scans' cells and each cell's updates."""

    def __init__(self, k: int) -> None:
        self.pending: list[list[np.ndarray]] = [[] for _ in range(k)]
        self.cells = [np.zeros(SIDE * SIDE, dtype=np.int32) for _ in range(k)]

    def close(self, adopted: int | None = None) -> None:
        for i, (p, c) in enumerate(zip(self.pending, self.cells, strict=True)):
            left = int(c.sum())
            COUNTS["cell_updates_adopted" if i == adopted else "cell_updates_never_read"] += left
            COUNTS["insertions_applied" if i == adopted else "insertions_skippable"] += len(p)
        self.pending, self.cells = [], []


TALLY: list[Tally] = []
_init, _age, _score = hd.DriftBank.__init__, hd.DriftBank.age, hd.DriftBank.score


def _hooked_init(self, *a, **k) -> None:
    _init(self, *a, **k)
    for t in TALLY:
        t.close()
    TALLY[:] = [Tally(len(self.branches))]
    COUNTS["banks"] += 1


def _hooked_age(self, rec, upto, model, per_branch) -> int:
    a, start = self.ref_upto, self.start
    out = _age(self, rec, upto, model, per_branch)
    cut = min(max(start, a), self.ref_upto)
    if self.ref_upto > cut:
        own = [np.array(b.poses[cut - start : self.ref_upto - start]) for b in self.branches]
        t = TALLY[-1]
        for i, (b, beams) in enumerate(zip(self.branches, rec.beams_each(cut, self.ref_upto, own),
                                           strict=True)):  # fmt: skip
            keys = world_keys(b.ref, MODEL.updates(b.ref, beams)[0])
            np.add.at(t.cells[i], keys, 1)
            t.pending[i].append(np.unique(keys))
            COUNTS["cell_updates"] += len(keys)
            COUNTS["insertions"] += 1
    return out


def _hooked_score(self, beam_model, ref, ref_upto, estimate, sens, ranges, kinds, travel):
    cfg = self.cfg
    due = travel >= self.next_travel and self.branches and self.ref_upto == ref_upto
    if due and len(kinds):
        t = TALLY[-1]
        COUNTS["scores"] += 1
        for i, b in enumerate(self.branches):
            g = b.ref
            w = compose(b.pose[None, :], sens)
            r = np.arange(0.5 * g.resolution, cfg.max_range_m + 3 * cfg.sigma_hit_m, g.resolution)
            row, col = g.cell_of(w[:, :1] + np.cos(w[:, 2:]) * r, w[:, 1:2] + np.sin(w[:, 2:]) * r)
            read = np.unique(world_keys(g, (row * g.shape[1] + col)[g.inside(row, col)]))
            COUNTS["cell_updates_read"] += int(t.cells[i][read].sum())
            t.cells[i][read] = 0
            meet = [j for j, p in enumerate(t.pending[i]) if np.isin(p, read).any()]
            last = meet[-1] + 1 if meet else 0
            COUNTS["insertions_applied"] += last
            COUNTS["scores_deferring"] += last < len(t.pending[i])
            t.pending[i] = t.pending[i][last:]
    won = _score(self, beam_model, ref, ref_upto, estimate, sens, ranges, kinds, travel)
    if won is not None:
        TALLY[-1].close(self.branches.index(won.branch))
        TALLY.clear()
    return won


def report() -> dict:
    for t in TALLY:
        t.close()
    TALLY.clear()
    return {"bench": "branch_reads", **COUNTS}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--distance", type=float, default=70.0)
    ap.add_argument("--ir-real", type=Path, help="a laser log folder: bench/ir_real.py's runs")
    ap.add_argument("--replay", type=Path, help="a daemon log (.mcap): hilnav replay of it")
    args, rest = ap.parse_known_args(argv)
    hd.DriftBank.__init__, hd.DriftBank.age = _hooked_init, _hooked_age  # type: ignore[method-assign]
    hd.DriftBank.score = _hooked_score  # type: ignore[method-assign]
    if args.replay is not None:
        import tempfile

        from hilnav.cli import main as hilnav_main

        with tempfile.TemporaryDirectory() as tmp:
            out = str(Path(tmp) / "replay.mcap")
            hilnav_main(["replay", str(args.replay), "--out", out, "--no-progress"])
    elif args.ir_real is not None:
        import ir_real

        ir_real.main([str(args.ir_real), *rest])
    else:
        import grid_mapping as gm

        run = gm.simulate(distance_m=args.distance, seed=args.seed)
        da = gm.map_with_da(run, 0.05, seed=args.seed)
        COUNTS["map_crc_with_da"] = gm._crc(da.grid)  # type: ignore[assignment]
    print(json.dumps(report()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
