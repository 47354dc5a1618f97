"""The page of a ranking (``kinegrasp rank --report``), the same for every robot.

A sortable table of the candidates, best first (P(FC) with its Wilson 95% interval, Q's
mean, standard deviation and skewness over the force-closure draws, Q nominal, the arm's
elbow coordinate, the draws per outcome and in all), and per candidate one 3-D scene drawn
on demand (its *show 3-D* button): the whole robot closed on the object in the world (robot
base) frame, as the report page draws it
(:func:`~kinegrasp_env.toolkit.report.robot.grasp_scene`), with the arm's skeleton at the
ranking's first draws (the same rows for every candidate: common noise), toggled in the
legend; it opens on the whole robot (candidates that differ by their elbow show it), a
button switches to a close-up of the object. Pages open offline and are deterministic.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from kinegrasp_env.montecarlo.draws import OUTCOMES
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.toolkit.report.arms import NoisyArms
from kinegrasp_env.toolkit.report.html import (
    Figure,
    command_block,
    esc,
    note,
    page,
    settings_table,
)
from kinegrasp_env.toolkit.report.page import fmt, versions
from kinegrasp_env.toolkit.report.plotly import MeshLibrary
from kinegrasp_env.toolkit.report.robot import (
    geometry_note,
    grasp_scene,
    grasps_geometry,
)
from kinegrasp_env.world.grasps import Grasp
from kinegrasp_env.world.objects import GraspObject

RANK_COLUMNS = ("rank", "id", "P(FC)", "95% CI", "Q mean", "Q std", "Q skewness",
                "Q nominal", "elbow [rad]", *(o.replace("_", " ") for o in OUTCOMES), "draws",
                "3-D")
#: The hold scores a row may carry (its ``holds``: key -> value) and their column headers,
#: shown before ``3-D`` where any row has them.
HOLD_HEADERS = {"p_hold_static": "P(hold, static)", "p_hold": "P(hold)",
                "hold_margin": "hold margin"}


def columns(hold_keys: Sequence[str], certified: bool = False) -> tuple[str, ...]:
    """The table's headers with the hold scores ``hold_keys`` (keys of
    :data:`HOLD_HEADERS`) and, for an adaptive run (``certified``), its labels."""
    return (*RANK_COLUMNS[:-1], *(HOLD_HEADERS[k] for k in hold_keys),
            *(("certified",) if certified else ()), RANK_COLUMNS[-1])


def elbow_coordinates(description: RobotDescription, grasps: Sequence[Grasp]) -> list[float]:
    """Each grasp's elbow coordinate, radians: a 7-joint arm's elbow angle on its
    self-motion, another arm's IK-branch coordinate (:func:`~kinegrasp_env.robot.
    branch_motion.elbow_motion`); NaN where the arm has none (a 7-joint arm without
    ``arm_angle_links``)."""
    from kinegrasp_env.robot.branch_motion import elbow_motion

    try:
        motion = elbow_motion(description)
    except ValueError:
        return [math.nan] * len(grasps)
    q = np.stack([np.asarray(g.q0, dtype=float) for g in grasps])
    return [float(v) for v in motion.elbow_angle(q)]


def rank_row(position: int, row: dict, elbow: float, key: str,
             hold_keys: Sequence[str] = ()) -> str:
    """One sortable table row (numbers in ``data-value``), with the hold scores
    ``hold_keys`` of its ``holds`` ('-' where it has none) and an adaptive run's label
    (its ``certified``, where it has one)."""
    def num(value, text):
        finite = value is not None and math.isfinite(value)
        return f'<td data-value="{value if finite else "NaN"}">{text if finite else "-"}</td>'

    cells = [num(position, str(position)), f'<td class="kg-text">{esc(row["id"])}</td>',
             num(row["p_fc"], f'{row["p_fc"]:.4f}'),
             num(row["p_fc_lo"], f'{row["p_fc_lo"]:.4f} .. {row["p_fc_hi"]:.4f}'),
             num(row["q_mean"], fmt(row["q_mean"])), num(row["q_std"], fmt(row["q_std"])),
             num(row.get("q_skew"), fmt(row.get("q_skew"), 3)),
             num(row["q_nominal"], fmt(row["q_nominal"])), num(elbow, f"{elbow:.3f}"),
             *(num(count, str(count)) for count in
               (row.get("outcomes", {}).get(name) for name in OUTCOMES)),
             num(row["samples"], str(row["samples"])),
             *(num(value, fmt(value, 3)) for value in
               (row.get("holds", {}).get(k) for k in hold_keys)),
             *([f'<td class="kg-text">{esc(row["certified"])}</td>'] if "certified" in row
               else []),
             f'<td><button class="kg-show" data-detail="detail-{key}" '
             f'onclick="kgToggle(this)">show 3-D</button></td>']
    return (f'<tr class="kg-item" data-detail="detail-{key}" data-id="{esc(row["id"])}">'
            f'{"".join(cells)}</tr>')


def rank_page(description: RobotDescription, objects: Mapping[str, GraspObject],
              grasps: Sequence[Grasp], rows: Sequence[dict], *, command: str,
              settings: dict, arms: Sequence[NoisyArms] | None = None, friction: float = 0.5,
              num_edges: int = 8, certificate: str | None = None) -> str:
    """The HTML page of a ranking.

    Args:
        description: the robot; objects: object name -> object, for every candidate's.
        grasps: the candidates, in file order.
        rows: best first; each with ``index`` (into grasps), ``id``, ``p_fc``, ``p_fc_lo``,
            ``p_fc_hi``, ``q_mean``, ``q_std``, ``q_nominal``, ``samples``, and where known
            ``q_skew``, ``outcomes`` (outcome name -> draws) and ``holds`` (hold score ->
            value, keys of :data:`HOLD_HEADERS`: a column each where any row has it) and, of
            an adaptive run, ``certified`` (its label: a column when every row has one).
        command: the command line that reproduces the page; settings: name -> value.
        arms: per candidate (file order), the arm at the ranking's first draws (None: none).
        certificate: what an adaptive run certified, in words (shown under the table).
    """
    chosen = [grasps[row["index"]] for row in rows]
    placed = [objects[g.object] for g in chosen]
    closings, geometry = grasps_geometry(description, placed, chosen)
    elbows = elbow_coordinates(description, chosen)
    hold_keys = [k for k in HOLD_HEADERS if any(k in row.get("holds", {}) for row in rows)]
    headers = columns(hold_keys, certified=bool(rows) and all("certified" in r for r in rows))
    library, figures, body_rows = MeshLibrary(), [], []
    for position, (row, grasp, obj, (_, did_close)) in enumerate(
            zip(rows, chosen, placed, closings, strict=True), 1):
        key = f"c{row['index']}"
        k = position - 1
        figure = Figure(f"{key}-scene", grasp_scene(
            description, obj, grasp, geometry, 2 * k, 2 * k + 1, library, did_close=did_close,
            friction=friction, num_edges=num_edges, whole_first=True,
            title=f"{description.name}: {obj.name} grasp {grasp.id}, world (robot base) frame",
            arms=None if arms is None else arms[row["index"]]), "100%", "520px", lazy=True)
        figures.append(figure)
        body_rows.append(rank_row(position, row, elbows[k], key, hold_keys))
        body_rows.append(f'<tr id="detail-{key}" style="display: none;"><td colspan='
                         f'"{len(headers)}">{figure.div()}</td></tr>')
    head = "".join(f'<th{" class=kg-text" if c in ("id", "certified") else ""}>{esc(c)}</th>'
                   for c in headers)
    names = ", ".join(dict.fromkeys(o.name for o in placed))
    shown = "" if arms is None else (
        f", with the arm's skeleton at the ranking's first {len(arms[0].q)} draws (the same "
        "rows for every candidate), toggled in the legend")
    title = f"kinegrasp ranking: robot {description.name}, {len(rows)} candidates of {names}"
    body = (f"<h1>{esc(title)}</h1><p class='kg-headline'>Click a column header to sort; "
            "<i>show 3-D</i> draws a candidate's scene: the whole robot closed on the object "
            f"(world frame){esc(shown)}.</p>"
            f'<table class="kg-sortable"><thead><tr>{head}</tr></thead>'
            f"<tbody>{''.join(body_rows)}</tbody></table>"
            + ("" if certificate is None else f"<p class='kg-headline'>{esc(certificate)}</p>")
            + f"{note(geometry_note(geometry))}"
            f"<h2>Settings</h2>{settings_table(settings)}"
            f"<h2>Command that reproduces this page</h2>{command_block(command)}")
    return page(title, body, figures, library, versions())
