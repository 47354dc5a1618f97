"""Which grasp ``evaluate``, ``report``, ``elbow`` and ``sensitivity`` take: entry ``--grasp``
of an object's shipped set, or grasp ``--grasp`` (an id, else an index) of a grasp file or a
palm-pose file (``--grasps FILE``; a palm-pose candidate is solved to a grasp first).
"""

from __future__ import annotations

import sys
from pathlib import Path

from kinegrasp_env.cli.common import CLIError, reported, shipped_grasp

#: ``evaluate``'s and ``report``'s object when neither --object nor --grasps is given.
EVALUATE_OBJECT = "spray_flask"


def chosen_grasp(args):
    """``(index, grasp)`` for ``evaluate`` and ``report``: grasp ``--grasp`` (an id in the
    file, else an index) of ``--grasps FILE``, or without it entry ``--grasp`` of
    ``--object``'s shipped set (of ``--robot``'s, where the command has one). Sets
    ``args.object`` to the grasp's object."""
    if args.grasps is None:
        args.object = args.object or EVALUATE_OBJECT
        return shipped_grasp(args.object, args.grasp, getattr(args, "robot", None))
    return grasp_of_file(args)


def grasp_of_file(args):
    """``(index, grasp)``: grasp ``--grasp`` (an id, else an index) of ``--grasps FILE``, a
    grasp file or a palm-pose file (its candidate solved to a grasp for the file's robot or
    ``--robot``); sets ``args.object`` to the grasp's object."""
    from kinegrasp_env.toolkit.candidates import is_candidate_file

    if Path(args.grasps).is_dir():
        raise CLIError(f"--grasps {args.grasps} is a folder, not a grasp file")
    if is_candidate_file(args.grasps):
        return palm_pose_grasp(args)
    return file_grasp(args)


def file_grasp(args):
    """``(index, grasp)``: grasp ``--grasp`` (an id, else an index) of the grasp file
    ``--grasps``; sets ``args.object`` to its object (one line when ``--object`` names
    another, when the file holds no grasps or cannot be read)."""
    from kinegrasp_env.world.grasps import load_grasps

    with reported(ValueError):  # load_grasps: missing file, bad JSON, bad fields
        grasps = load_grasps(args.grasps)
    if not grasps:
        raise CLIError(f"--grasps {args.grasps} holds no grasps")
    index = id_index(args.grasp, [g.id for g in grasps], args.grasps)
    grasp = grasps[index]
    if args.object is not None and args.object != grasp.object:
        raise CLIError(f"--object {args.object}: grasp {grasp.id} of {args.grasps} is a grasp of "
                       f"{grasp.object}")
    args.object = grasp.object
    return index, grasp


def id_index(word: str, ids: list[str], source: str) -> int:
    """The index of ``word`` in ``ids``, the grasp ids of ``source`` (a file, or words that
    name a grasp set): an id, else an index; one line naming a few of the ids otherwise."""
    if ids.count(word) > 1:  # a file of several objects' grasps, each numbered from 0
        at = [str(i) for i, x in enumerate(ids) if x == word]
        raise CLIError(f"--grasp {word}: {len(at)} grasps of {source} have this id (of "
                       f"several objects); give one by its index ({', '.join(at[:8])})")
    if word in ids:
        return ids.index(word)
    try:
        index = int(word)
    except ValueError:
        index = -1
    if not 0 <= index < len(ids):
        shown = ", ".join(ids[:8]) + (", ..." if len(ids) > 8 else "")
        raise CLIError(f"--grasp {word}: no grasp with this id in {source} (ids: {shown}), "
                       f"and not an index 0..{len(ids) - 1}")
    return index


def read_palm_poses(path: str, robot: str | None):
    """A palm-pose file read and checked for every command that takes one
    (:func:`~kinegrasp_env.toolkit.candidates.read_candidates`: a bad entry or a robot
    conflict is one line); where neither the file nor ``robot`` (the command's ``--robot``)
    names the robot, a line on stderr says the candidates are the default robot's, which a
    user of another robot would not see otherwise."""
    from kinegrasp_env.toolkit.candidates import read_candidates

    with reported(ValueError):
        read = read_candidates(path, robot)
    if not read.robot_named:
        print(f"{path} names no robot: its candidates are solved for the default robot "
              f"{read.robot} (give a \"robot\" field or --robot for another)", file=sys.stderr)
    return read


def solve_candidates(read, chosen: list, path: str, *, friction: float = 0.5,
                     strict: bool = False) -> tuple[list, list]:
    """(grasps, rejected) of the ``chosen`` candidates of a palm-pose file (``read``:
    :func:`read_palm_poses`) solved to grasps (IK, clearance, closing) at ``friction``;
    each rejected one a line on stderr with its reason, or with ``strict`` a one-line
    error."""
    from kinegrasp_env.toolkit.candidates import solve_all

    grasps, rejected = solve_all(read.object, chosen, read.robot, friction)
    if strict and rejected:
        raise CLIError(f"candidate {rejected[0].id} of {path} is rejected: "
                       f"{rejected[0].reason} ({rejected[0].detail})")
    for r in rejected:
        print(f"candidate {r.id} rejected: {r.reason} ({r.detail})", file=sys.stderr)
    return grasps, rejected


def palm_pose_grasp(args):
    """``chosen_grasp`` for a palm-pose file: the chosen candidate solved to a grasp for the
    file's robot or ``--robot`` (:func:`solve_candidates`, strict)."""
    read = read_palm_poses(args.grasps, getattr(args, "robot", None))
    name, candidates = read.object, read.candidates
    index = id_index(args.grasp, [c.id for c in candidates], args.grasps)
    if args.object is not None and args.object != name:
        raise CLIError(f"--object {args.object}: {args.grasps} holds candidates of {name}")
    grasps, _ = solve_candidates(read, [candidates[index]], args.grasps, strict=True)
    args.object = name
    return index, grasps[0]


def grasp_shown(args, index: int, grasp) -> str:
    """How the console names an elbow run's grasp: its id in ``--grasps``' file, else its
    index in the robot's shipped set (as ``--grasp`` chose it)."""
    return str(grasp.id) if getattr(args, "grasps", None) else str(index)
