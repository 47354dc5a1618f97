"""Make the README's pictures with the README's own commands.

Run from anywhere: ``python scripts/make_readme_images.py [WORD ...] [--list]``.

It reads the console and bash blocks of ``README.md`` and runs, in README order and from the
repository root, the ``kinegrasp`` commands that write into ``out/tour/`` (the tour's scratch
folder, ignored by git) or into ``docs/images/`` (a command the README shows for making a
picture): all of them, or those whose text contains one of the WORDs, together with the earlier
commands that write the ``out/tour/`` files they read (``rank`` reads what ``plan`` wrote).
Then every file a command wrote under ``out/tour/`` is copied to ``docs/images/`` under the same
relative name (``out/tour/fig7/fig7_drill.png`` -> ``docs/images/fig7/fig7_drill.png``) when
the README refers to that name or ``docs/images/`` already holds it; other files (grasp files,
CSVs nobody shows) stay in ``out/tour/``. So the committed pictures are what the README's
commands produce. ``--list`` prints the commands it would run and runs nothing.

The README parser here (blocks, their ``<!-- readme-test: ... -->`` markers, commands, shown
outputs, the files a command writes) is also what ``tests/test_readme.py`` runs the README with.
"""

from __future__ import annotations

import argparse
import functools
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
TOUR = "out/tour"
IMAGES = "docs/images"
MODES = ("exact", "stats", "skip")
_FENCE = re.compile(r"^```(\w*)\s*$")
_MARKER = re.compile(r"^<!--\s*readme-test:(.*?)-->\s*$")


@dataclass(frozen=True)
class Marker:
    """How a test runs a console block: ``exact`` (the shown output, line for line),
    ``stats`` (``--samples`` replaced by ``samples``; structure and intervals compared) or
    ``skip`` (not run, ``reason`` says why); ``expensive`` marks the test as slow."""

    mode: str
    samples: int | None = None
    expensive: bool = False
    reason: str = ""
    line: int = 0


@dataclass(frozen=True)
class Step:
    """One shown command (continuation lines joined) and the stdout lines shown under it."""

    command: str
    output: tuple[str, ...]


@dataclass(frozen=True)
class Block:
    """A fenced block of the README: ``lang`` (console, bash, python, ...), the 1-based line
    of its opening fence, the markers right above it and its steps (console and bash only)."""

    index: int
    lang: str
    line: int
    markers: tuple[Marker, ...]
    steps: tuple[Step, ...]
    text: str


def parse_marker(body: str, line: int) -> Marker:
    """``exact [expensive]``, ``stats samples=N [expensive]`` or ``skip reason=TEXT``."""
    words = body.split()
    if not words or words[0] not in MODES:
        raise ValueError(f"README.md line {line}: readme-test marker {body.strip()!r}: the "
                         f"mode must be one of {', '.join(MODES)}")
    mode, samples, expensive = words[0], None, False
    rest = body.strip()[len(mode):].strip()
    if mode == "skip":
        if not rest.startswith("reason=") or not rest[len("reason="):].strip():
            raise ValueError(f"README.md line {line}: a skip marker needs reason=TEXT")
        return Marker("skip", reason=rest[len("reason="):].strip(), line=line)
    for word in rest.split():
        if word == "expensive":
            expensive = True
        elif word.startswith("samples=") and word[8:].isdigit() and int(word[8:]) > 0:
            samples = int(word[8:])
        else:
            raise ValueError(f"README.md line {line}: readme-test marker: unknown option "
                             f"{word!r} (expensive, samples=N)")
    if (mode == "stats") != (samples is not None):
        raise ValueError(f"README.md line {line}: samples=N goes with stats, and stats needs it")
    return Marker(mode, samples, expensive, line=line)


def markers_above(lines: list[str], fence: int) -> tuple[Marker, ...]:
    """The marker comments on the lines right above line index ``fence`` (0-based)."""
    found = []
    i = fence - 1
    while i >= 0 and (match := _MARKER.match(lines[i].strip())):
        found.append(parse_marker(match.group(1), i + 1))
        i -= 1
    return tuple(reversed(found))


def console_steps(body: list[str]) -> tuple[Step, ...]:
    """``$ `` lines are commands (a trailing backslash continues one), the rest their output."""
    steps: list[tuple[str, list[str]]] = []
    continuing = False
    for line in body:
        if continuing:
            steps[-1] = (steps[-1][0] + " " + line.strip().removesuffix("\\").strip(),
                         steps[-1][1])
            continuing = line.rstrip().endswith("\\")
        elif line.startswith("$ "):
            steps.append((line[2:].rstrip().removesuffix("\\").strip(), []))
            continuing = line.rstrip().endswith("\\")
        elif not steps:
            raise ValueError(f"console block: output before any command: {line!r}")
        else:
            steps[-1][1].append(line.rstrip())
    return tuple(Step(command, tuple(output)) for command, output in steps)


def bash_steps(body: list[str]) -> tuple[Step, ...]:
    """Each command line (comments dropped, continuation lines joined); no output shown."""
    commands: list[str] = []
    continuing = False
    for line in body:
        text = re.sub(r"(^|\s)#.*$", "", line).strip()
        if continuing:
            commands[-1] += " " + text.removesuffix("\\").strip()
        elif text:
            commands.append(text.removesuffix("\\").strip())
        continuing = text.endswith("\\")
    return tuple(Step(command, ()) for command in commands)


def readme_blocks(text: str | None = None) -> list[Block]:
    """Every fenced block of the README, in order."""
    lines = (README.read_text() if text is None else text).splitlines()
    blocks: list[Block] = []
    i = 0
    while i < len(lines):
        match = _FENCE.match(lines[i])
        if not match:
            i += 1
            continue
        end = i + 1
        while end < len(lines) and lines[end].rstrip() != "```":
            end += 1
        lang, body = match.group(1), lines[i + 1:end]
        steps = (console_steps(body) if lang == "console"
                 else bash_steps(body) if lang == "bash" else ())
        blocks.append(Block(len(blocks), lang, i + 1, markers_above(lines, i), steps,
                            "\n".join(body)))
        i = end + 1
    return blocks


def kinegrasp_argvs(command: str) -> list[list[str]]:
    """The argument lists of the ``kinegrasp`` calls in a shell command line (split at
    ``&&``, ``;`` and ``|``)."""
    argvs = []
    for piece in re.split(r"&&|;|\|", command):
        words = shlex.split(piece)
        if words and Path(words[0]).name == "kinegrasp":
            argvs.append(words[1:])
    return argvs


def command_targets(command: str) -> list[str]:
    """See :func:`parsed_targets` (a list, for the caller to keep)."""
    return list(parsed_targets(command))


@functools.cache
def parsed_targets(command: str) -> tuple[str, ...]:
    """The paths (files or folders, as written) that the ``kinegrasp`` calls of ``command``
    write, read from the CLI's own parser: ``--out``, ``--plot`` and ``--report`` with their
    defaults, ``reproduce``'s ``out/<figure>`` and ``rank``'s ``<out>.partial.jsonl``."""
    from kinegrasp_env.cli.main import build_parser

    targets = []
    for argv in kinegrasp_argvs(command):
        try:
            args, _ = build_parser().parse_known_args(argv)
        except SystemExit:  # --help, --version, or not a command
            continue
        if args.command == "reproduce" and args.out is None:
            targets.append(f"out/{args.figure}")
        for name in ("out", "plot", "report"):
            value = getattr(args, name, None)
            if isinstance(value, str):
                targets.append(value)
        if args.command == "rank":
            targets.append(f"{args.out}.partial.jsonl")
    return tuple(targets)


def shown_commands(blocks: list[Block]) -> list[str]:
    """Every command of the console and bash blocks, in README order."""
    return [step.command for block in blocks if block.lang in ("console", "bash")
            for step in block.steps]


def covers(target: str, path: str) -> bool:
    """Whether writing ``target`` (a file or a folder) writes ``path``."""
    target = target.rstrip("/")
    return path == target or path.startswith(target + "/")


def env_with_kinegrasp(bin_dir: Path) -> dict[str, str]:
    """The environment with a ``kinegrasp`` on PATH that runs this Python's package (a shim
    written into ``bin_dir``), whatever the PATH of the caller."""
    shim = bin_dir / "kinegrasp"
    shim.write_text(f'#!/bin/sh\nexec "{sys.executable}" -m kinegrasp_env.cli "$@"\n')
    shim.chmod(0o755)
    env = dict(os.environ)
    env["PATH"] = f"{bin_dir}{os.pathsep}{env.get('PATH', '')}"
    return env


def wanted_pictures(readme_text: str) -> list[str]:
    """The docs/images/ files the README shows as pictures, and those committed there."""
    shown = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", readme_text)
    held = [p.relative_to(ROOT).as_posix() for p in (ROOT / IMAGES).rglob("*") if p.is_file()]
    return sorted({path for path in shown + held if covers(IMAGES, path)})


def makes_picture(targets: list[str], pictures: list[str]) -> bool:
    """Whether a command writing ``targets`` writes one of ``pictures`` (docs/images/X),
    as out/tour/X or as docs/images/X."""
    return any(covers(t, picture) or covers(t, TOUR + picture[len(IMAGES):])
               for t in targets for picture in pictures)


def tour_inputs(command: str, targets: list[str]) -> list[str]:
    """The out/tour/ paths ``command`` names without writing them (files it reads)."""
    return [word for word in shlex.split(command)
            if covers(TOUR, word) and not any(covers(t, word) for t in targets)]


def producers(commands: list[str], upto: int, paths: list[str]) -> list[int]:
    """Indices, ascending, of the commands among ``commands[:upto]`` that write ``paths``
    (the last writer of each) and, transitively, of those writing what they read."""
    chosen: set[int] = set()
    wanted = [(path, upto) for path in paths]
    while wanted:
        path, before = wanted.pop()
        for index in range(before - 1, -1, -1):
            targets = command_targets(commands[index])
            if any(covers(t, path) for t in targets):
                if index not in chosen:
                    chosen.add(index)
                    wanted += [(p, index) for p in tour_inputs(commands[index], targets)]
                break
    return sorted(chosen)


def picture_commands(blocks: list[Block], words: list[str], pictures: list[str]) -> list[str]:
    """The commands that write one of ``pictures`` (those containing one of ``words`` if any),
    plus the earlier ones writing the out/tour/ files they read, in README order."""
    commands = shown_commands(blocks)
    chosen: set[int] = set()
    for index, command in enumerate(commands):
        targets = command_targets(command)
        if makes_picture(targets, pictures) and (not words or any(w in command for w in words)):
            chosen |= {index, *producers(commands, index, tour_inputs(command, targets))}
    return [commands[index] for index in sorted(chosen)]


def snapshot(folder: Path) -> dict[Path, tuple[int, int]]:
    """(mtime in ns, size) of every file under ``folder``."""
    return {p: (p.stat().st_mtime_ns, p.stat().st_size)
            for p in folder.rglob("*") if p.is_file()} if folder.is_dir() else {}


def copy_written(written: list[Path], pictures: list[str]) -> None:
    """Copy the files written under out/tour/ that are ``pictures`` to docs/images/."""
    for path in sorted(written):
        relative = path.relative_to(ROOT / TOUR).as_posix()
        destination = ROOT / IMAGES / relative
        if f"{IMAGES}/{relative}" in pictures:
            destination.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(path, destination)
            print(f"copied {TOUR}/{relative} -> {IMAGES}/{relative}")
        else:
            print(f"kept {TOUR}/{relative} (the README does not show it)")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("words", nargs="*", help="run only the commands containing one of these")
    parser.add_argument("--list", action="store_true", help="print the commands, run nothing")
    args = parser.parse_args(argv)
    readme_text = README.read_text()
    pictures = wanted_pictures(readme_text)
    commands = picture_commands(readme_blocks(readme_text), args.words, pictures)
    if not commands:
        print(f"no README command writing a picture of {IMAGES}/ matches {args.words}")
        return 1
    made = [p for p in pictures
            if any(makes_picture(command_targets(c), [p]) for c in commands)]
    for picture in [] if args.words else pictures:
        if picture not in made:
            print(f"note: no README command writing out/tour/ makes {picture}; left as it is")
    if args.list:
        print("\n".join(commands))
        return 0
    with tempfile.TemporaryDirectory() as bin_dir:
        env = env_with_kinegrasp(Path(bin_dir))
        for command in commands:
            print(f"$ {command}", flush=True)
            before = snapshot(ROOT / TOUR)
            subprocess.run(["bash", "-c", command], cwd=ROOT, env=env, check=True)
            after = snapshot(ROOT / TOUR)
            copy_written([p for p, stamp in after.items() if before.get(p) != stamp],
                         pictures)
    return 0


if __name__ == "__main__":
    sys.exit(main())
