"""The two implementations of the fast closing on the default robot's fingers: the batched
loop every finger can take (:class:`~kinegrasp_env.closing.generic_fast.FastRobotHand` with
``compiled=False``: GJK bounds, exact pairs, halving) against the compiled capsule loop the
fast engine closes the SDH's fingers with (:class:`~kinegrasp_env.montecarlo.batched_engine.
RobotFastEngine`: :mod:`~kinegrasp_env.closing.capsule_fingers`, grid gaps, exact pairs within a
band, bisection), on the same draws: the shipped grasps of the four objects, joint noise of
sigma 0.0133 rad, ``--draws`` each.

For each grasp: the share of draws with the same outcome, the outcome pairs where they
differ, P(FC) of both and their paired difference (a 95% t-interval on the per-draw
differences, Bonferroni-corrected over the grasps), and the time per draw of each engine.
Every differing draw is put in one class:

* ``verdict``: both closings touch with the same fingers and links; only the force-closure
  verdict differs (the contacts lie within the closings' tolerances of each other and the
  grasp is at the edge of force closure);
* ``links``: both touch, with other links (a link that grazes the object within the contact
  tolerance in one closing and not in the other);
* ``reach``: one closing misses (a finger reaches its limits or the object is grazed) where
  the other touches;
* ``start``: the start-collision verdict differs (both check it alike: never expected).

    python benchmarks/description_agreement.py [--draws 2000] [--objects cube drill ...]

The figures go to ``benchmarks/results/description_agreement.json`` and the table to
``docs/guides/robot.md`` (``--no-json``: neither).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from results_file import add_options, publish, settings
from scipy import stats

from kinegrasp_env.closing.generic_fast import FastRobotHand
from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE, MISSED, OUTCOMES, START_COLLISION
from kinegrasp_env.montecarlo.engines import make_engine
from kinegrasp_env.world.grasps import shipped_grasps

DOC = Path(__file__).resolve().parents[1] / "docs" / "guides" / "robot.md"
START, END = "<!-- description-agreement:start -->", "<!-- description-agreement:end -->"
SIGMA = 0.0133
#: The classes of a differing draw (module docstring).
CLASSES = ("verdict", "links", "reach", "start")


def pattern(draws, i: int) -> tuple:
    """The (finger, link) pairs that touch in draw i."""
    k = int(draws.n_contacts[i])
    return tuple(sorted(zip(draws.finger[i, :k].tolist(), draws.link[i, :k].tolist(),
                            strict=True)))


def kind(loop, kernel, i: int) -> str:
    """The class of a differing draw (module docstring)."""
    a, b = int(loop.outcome[i]), int(kernel.outcome[i])
    if START_COLLISION in (a, b):
        return "start"
    if MISSED in (a, b):
        return "reach"
    return "verdict" if pattern(loop, i) == pattern(kernel, i) else "links"


def contact_offsets(a, b, same: np.ndarray) -> np.ndarray:
    """Distances (metres) between the contacts of the draws ``same`` where both closings
    touch with the same finger links (each draw's contacts in (finger, link) order)."""
    out = []
    for i in np.flatnonzero(same):
        if pattern(a, i) == pattern(b, i) and a.n_contacts[i]:
            k = int(a.n_contacts[i])
            oa = np.lexsort((a.link[i, :k], a.finger[i, :k]))
            ob = np.lexsort((b.link[i, :k], b.finger[i, :k]))
            out.extend(np.linalg.norm(a.points[i, oa] - b.points[i, ob], axis=1))
    return np.array(out)


def grasp_row(obj: str, index: int, q0: np.ndarray, loop, kernel, draws: int,
              corrected: float, names: tuple[str, str] = ("loop", "kernel")) -> dict:
    rng = np.random.default_rng(index)
    q = np.repeat(q0[None], draws, axis=0)
    q[:, :7] += rng.normal(0.0, SIGMA, (draws, 7))
    start = time.perf_counter()
    a = loop.run(q)
    t_loop = time.perf_counter() - start
    start = time.perf_counter()
    b = kernel.run(q)
    t_kernel = time.perf_counter() - start
    differ = np.flatnonzero(a.outcome != b.outcome)
    diff = (a.outcome == FORCE_CLOSURE).astype(float) - (b.outcome == FORCE_CLOSURE)
    half = stats.t.ppf(1 - corrected / 2, draws - 1) * diff.std(ddof=1) / np.sqrt(draws)
    classes = {name: 0 for name in CLASSES}
    for i in differ:
        classes[kind(a, b, i)] += 1
    pairs: dict[str, int] = {}
    for i in differ:
        key = f"{OUTCOMES[b.outcome[i]]}->{OUTCOMES[a.outcome[i]]}"
        pairs[key] = pairs.get(key, 0) + 1
    offsets = contact_offsets(a, b, a.outcome == b.outcome)
    first, second = names
    return {"object": obj, "grasp": index, "draws": draws, "same": 1 - differ.size / draws,
            f"p_fc_{first}": float((a.outcome == FORCE_CLOSURE).mean()),
            f"p_fc_{second}": float((b.outcome == FORCE_CLOSURE).mean()),
            "difference": float(diff.mean()), "interval": [float(diff.mean() - half),
                                                         float(diff.mean() + half)],
            "classes": classes, "pairs": pairs,
            "contacts": int(offsets.size),
            "contact_offset_median": float(np.median(offsets)) if offsets.size else None,
            "contact_offset_max": float(offsets.max()) if offsets.size else None,
            f"us_per_draw_{first}": 1e6 * t_loop / draws,
            f"us_per_draw_{second}": 1e6 * t_kernel / draws}


def markdown(result: dict, names: tuple[str, str] = ("loop", "kernel")) -> str:
    rows = result["grasps"]
    first, second = names
    lines = ["| object | draws | same outcome | worst grasp | P(FC) intervals holding 0 "
             f"| verdict / links / reach / start | us a draw: {first}, {second} |",
             "|---|---|---|---|---|---|---|"]
    for obj in dict.fromkeys(r["object"] for r in rows):
        mine = [r for r in rows if r["object"] == obj]
        n = sum(r["draws"] for r in mine)
        same = sum(r["same"] * r["draws"] for r in mine) / n
        held = sum(r["interval"][0] <= 0 <= r["interval"][1] for r in mine)
        classes = [sum(r["classes"][c] for r in mine) for c in CLASSES]
        lines.append(f"| {obj} | {n} | {100 * same:.2f}% | "
                     f"{100 * min(r['same'] for r in mine):.1f}% | {held} of {len(mine)} | "
                     f"{' / '.join(map(str, classes))} | "
                     f"{np.mean([r[f'us_per_draw_{first}'] for r in mine]):.0f}, "
                     f"{np.mean([r[f'us_per_draw_{second}'] for r in mine]):.0f} |")
    total = result["summary"]
    classes = " / ".join(str(total["classes"][c]) for c in CLASSES)
    lines.append(f"| all | {total['draws']} | {100 * total['same']:.2f}% | "
                 f"{100 * total['worst']:.1f}% | {total['held']} of {total['grasps']} | "
                 f"{classes} | {total[f'us_{first}']:.0f}, {total[f'us_{second}']:.0f} |")
    return "\n".join(lines)


def summarize(rows: list[dict], names: tuple[str, str] = ("loop", "kernel")) -> dict:
    """The grasps' rows summed: draws, same outcome, the worst grasp, intervals holding 0,
    the classes, the contacts' offsets and each closing's time a draw."""
    n = sum(r["draws"] for r in rows)
    medians = [r["contact_offset_median"] for r in rows if r["contacts"]]
    return {"draws": n, "grasps": len(rows),
            "same": sum(r["same"] * r["draws"] for r in rows) / n,
            "worst": min(r["same"] for r in rows),
            "held": sum(r["interval"][0] <= 0 <= r["interval"][1] for r in rows),
            "classes": {c: sum(r["classes"][c] for r in rows) for c in CLASSES},
            "contact_offset_median_worst": max(medians, default=None),
            "contact_offset_max": max((r["contact_offset_max"] for r in rows
                                       if r["contacts"]), default=None),
            **{f"us_{name}": float(np.mean([r[f"us_per_draw_{name}"] for r in rows]))
               for name in names}}


def compare(objects: list[str], pair_of, draws: int,
            names: tuple[str, str] = ("loop", "kernel")) -> list[dict]:
    """:func:`grasp_row` of every shipped grasp of ``objects``: ``pair_of(object)`` gives the
    two engines compared on it (closed afterwards), each warmed on one draw first."""
    grasps = {obj: shipped_grasps(obj) for obj in objects}
    corrected = 0.05 / sum(len(g) for g in grasps.values())
    rows = []
    for obj, kept in grasps.items():
        first, second = pair_of(obj)
        first.run(kept[0].q0[None]), second.run(kept[0].q0[None])  # compiled, warmed
        for index, grasp in enumerate(kept):
            rows.append(grasp_row(obj, index, grasp.q0, first, second, draws, corrected,
                                  names))
            median = rows[-1]["contact_offset_median"] or 0.0
            print(f"{obj} {index}: same {rows[-1]['same']:.4f}, contacts {median:.1e} m "
                  "apart (median)", flush=True)
        first.close(), second.close()
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--objects", nargs="+", default=["cube", "drill", "mug", "spray_flask"])
    parser.add_argument("--draws", type=int, default=2000)
    add_options(parser, __file__)
    args = parser.parse_args()

    def pair_of(obj: str) -> tuple:
        loop, kernel = make_engine("fast", "kuka_sdh", obj), make_engine("fast", "kuka_sdh", obj)
        loop.hand = FastRobotHand(loop.description, loop.obj, compiled=False)
        return loop, kernel

    rows = compare(args.objects, pair_of, args.draws)
    result = {"sigma": SIGMA, "grasps": rows, "summary": summarize(rows),
              "settings": settings(args)}
    publish(__file__, result, args, markdown(result), DOC, (START, END))

if __name__ == "__main__":
    main()
