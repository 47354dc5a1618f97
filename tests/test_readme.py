"""The README's promises: its console blocks print what it shows, its pictures come from
commands it shows, its Python runs, and its commands write nothing git would track.

Every ```console block carries one or more markers right above it (README parser:
``scripts/make_readme_images.py``):

- ``<!-- readme-test: exact -->``: its commands run as shown, in order, in a scratch folder
  holding copies of the repository files they read (same relative paths, so the paths they
  print are the README's); every command's stdout must equal the shown output line for line
  (trailing blanks ignored; durations like ``drawn in 3026 ms`` masked, the one number that
  depends on the machine). For seeded commands: same seed, same numbers. A block that reads
  an out/tour/ file an earlier block writes (``rank out/tour/grasps.json`` after the tour's
  ``plan``) first gets it from that earlier command, run once per test run (not compared
  there). Blocks with ``kinegrasp screenshot`` skip without Chromium.
- ``<!-- readme-test: stats samples=N -->``: the same, with ``--samples`` replaced by N in the
  commands that take it (the others still compared exactly). The output of those commands is
  compared by structure and by intervals (``stats_problems``): as many lines, of the same
  kinds in the same order; a line that is not one of the statistic lines of ``STAT_LINES``
  equal exactly; statistic lines of a kind paired by their keys (a table may reorder its
  rows), the keys equal, paired lines equal once numbers and grasp ids are masked, the draw
  counts equal to N, and every proportion (P(FC), each outcome's share) inside the README's
  interval widened by the small run's own: the small run's 99.9% Wilson interval must overlap
  the README's 95% interval (the one the README shows; for a proportion shown
  without one, the Wilson 95% interval at the README's ``--samples``). With fixed seeds the
  verdict is deterministic; the rule only says how far a correct small run may land.
- ``<!-- readme-test: skip reason=... -->``: not run.

``expensive`` after the mode marks the test ``@pytest.mark.expensive``.
"""

from __future__ import annotations

import difflib
import importlib.util
import math
import re
import shlex
import shutil
import subprocess
import sys
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def _load_parser():
    """``scripts/make_readme_images.py`` as a module (the README parser it shares)."""
    spec = importlib.util.spec_from_file_location("make_readme_images",
                                                  ROOT / "scripts" / "make_readme_images.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


readme = _load_parser()
BLOCKS = readme.readme_blocks(README)
CONSOLE = [b for b in BLOCKS if b.lang == "console"]
CONSOLE_COMMANDS = [step.command for block in CONSOLE for step in block.steps]
#: Where each console block's first command is in CONSOLE_COMMANDS.
FIRST = {block.index: sum(len(b.steps) for b in CONSOLE[:i]) for i, block in enumerate(CONSOLE)}
#: Commands whose files a later console command reads, and what they wrote (this test run).
PREREQUISITES = {CONSOLE_COMMANDS[j] for i, command in enumerate(CONSOLE_COMMANDS)
                 for j in readme.producers(CONSOLE_COMMANDS, i, readme.tour_inputs(
                     command, readme.command_targets(command)))}
_MADE: dict[str, dict[str, bytes]] = {}


@dataclass(frozen=True)
class Page:
    """A Markdown page whose console blocks are run (the README, or a page of the docs site):
    its blocks, their commands in order, where each block's first command is among them, and
    the commands whose files a later block of the same page reads."""

    name: str
    console: tuple
    commands: tuple[str, ...]
    first: dict
    prerequisites: frozenset


def page_of(name: str, text: str) -> Page:
    """The :class:`Page` of Markdown ``text`` (``name``: where it comes from, for test ids)."""
    console = tuple(b for b in readme.readme_blocks(text) if b.lang == "console")
    commands = tuple(step.command for block in console for step in block.steps)
    first = {block.index: sum(len(b.steps) for b in console[:i])
             for i, block in enumerate(console)}
    needed = frozenset(commands[j] for i, command in enumerate(commands)
                       for j in readme.producers(list(commands), i, readme.tour_inputs(
                           command, readme.command_targets(command))))
    return Page(name, console, commands, first, needed)


README_PAGE = page_of("README.md", README)
#: The documentation site's pages (docs/**/*.md), their console blocks run the same way.
DOC_PAGES = [page_of(path.relative_to(ROOT).as_posix(), path.read_text())
             for path in sorted((ROOT / "docs").rglob("*.md"))]
_DURATION = re.compile(r"\bin \d+(?:\.\d+)? ?(?P<unit>ms|s)\b")

Z95, Z999 = 1.959964, 3.290527  # two-sided normal quantiles, 95% and 99.9%
_NUMBER = re.compile(r"(?<![A-Za-z_\d])[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?(?:v\d+)?")
_P = r"(?P<p>[01]\.\d+)"
_CI = r"(?P<lo>[01]\.\d+)"
_HI = r"(?P<hi>[01]\.\d+)"
#: The statistic lines: groups ``k_*`` are keys (pair lines, must be equal), ``p`` a
#: proportion with its interval ``lo``..``hi`` when shown, ``n`` the draws, ``counts``
#: ``name count`` pairs of outcomes; anything else on the line is only masked.
STAT_LINES = {
    "evaluate header": re.compile(r"^(?P<k_what>\S+ grasp .+), (?P<n>\d+) draws"
                                  r"(?P<k_friction>, friction mu .+)?$"),
    "evaluate P(FC)": re.compile(rf"^\s+P\(FC\)\s+= {_P}\s+\(95% CI {_CI} \.\. {_HI}\)$"),
    "evaluate Q": re.compile(r"^\s+Q \(Ferrari-Canny, dimensionless, \w+ contacts; mean, std, "
                             r"skewness over "
                             r"the force-closure draws\): nominal (?P<k_nominal>\S+), mean \S+, "
                             r"std \S+, skewness \S+, error \(nominal - mean\) \S+$"),
    "outcomes": re.compile(r"^\s+outcomes: (?P<counts>\w+ \d+(?:, \w+ \d+)*)$"),
    "rank row": re.compile(rf"^\s*\d+\s+(?P<k_id>\S+)\s+{_P}\s+{_CI}\.\.{_HI}\s+\S+\s+"
                           r"(?P<k_q_nominal>\S+)\s+(?P<n>\d+)$"),
    "report header": re.compile(rf"^(?P<k_what>\S+ grasp .+), (?P<n>\d+) draws: "
                                rf"P\(FC\) = {_P} \(95% CI {_CI} \.\. {_HI}\)$"),
    "report written": re.compile(r"^report written to (?P<k_path>\S+) \(\S+ MB\)$"),
    "screenshot": re.compile(r"^(?P<k_page>\S+): drawn in \d+ ms, (?P<k_errors>\d+) console "
                             r"errors; screenshot written to (?P<k_png>\S+)$"),
    "fig7 row": re.compile(rf"^(?P<k_object>\S+)\s+(?P<k_role>robust|fragile)\s+id \S+\s+"
                           r"(?:elbow \S+ rad |IK branch \S+ )?"
                           rf"P\(FC\) {_P} \(95% CI {_CI} \.\. {_HI}\), chosen at \S+$"),
    "fig7 gap": re.compile(r"^(?P<k_object>\S+)\s+robust - fragile \S+ \(95% CI \S+ \.\. \S+\), "
                           r"paired$"),
    "fig7 provenance": re.compile(r"^robust and fragile (?P<k_what>.+) chosen on (?P<n>\d+) "
                                  r"draws per candidate \(seed \d+, chunks \S+\), reported on "
                                  r"(?P=n) fresh draws \(chunks \S+\)$"),
}


def wilson(successes: float, n: int, z: float) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion (written here, not imported)."""
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return centre - half, centre + half


def proportion_problem(what: str, shown: tuple[float, float], p_run: float, n_run: int):
    """A message unless the run's 99.9% Wilson interval overlaps the README's interval."""
    lo, hi = wilson(p_run * n_run, n_run, Z999)
    if lo <= shown[1] and hi >= shown[0]:
        return None
    return (f"{what}: {p_run:.4f} at {n_run} draws (99.9% {lo:.4f}..{hi:.4f}) outside the "
            f"README's {shown[0]:.4f}..{shown[1]:.4f}")


def mask(line: str) -> str:
    """The line with every number (and grasp id like ``3v1``) as ``#``, blanks collapsed."""
    return " ".join(_NUMBER.sub("#", line).split())


def stat_line(line: str) -> re.Match | None:
    """The match of the first ``STAT_LINES`` pattern the line matches, or None."""
    for pattern in STAT_LINES.values():
        if match := pattern.match(line):
            return match
    return None


def classify(line: str) -> tuple[str, dict[str, str]] | None:
    """(kind, groups) of a statistic line, None for any other line."""
    match = stat_line(line)
    if match is None:
        return None
    return next(n for n, p in STAT_LINES.items() if p is match.re), match.groupdict()


def row_key(groups: dict[str, str]) -> tuple[str, ...]:
    """The key groups of a statistic line, in name order."""
    return tuple(v for k, v in sorted(groups.items()) if k.startswith("k_"))


def number_problems(name: str, shown: dict, now: dict, n_readme: int, n_run: int) -> list[str]:
    """Draw counts equal to the runs', proportions inside the widened README intervals."""
    problems = []
    if "n" in shown:
        if int(shown["n"]) != n_readme:
            problems.append(f"{name}: the README shows {shown['n']} draws, its command asks "
                            f"for {n_readme}")
        if int(now["n"]) != n_run:
            problems.append(f"{name}: {now['n']} draws, asked for {n_run}")
    if "p" in shown:
        p = float(shown["p"])
        interval = ((float(shown["lo"]), float(shown["hi"])) if shown.get("lo")
                    else wilson(p * n_readme, n_readme, Z95))
        label = " ".join([name, *row_key(shown)])
        problems.append(proportion_problem(label, interval, float(now["p"]), n_run))
    if "counts" in shown:  # another number of outcomes is a masked-line difference
        pairs = zip(_pairs(shown["counts"]), _pairs(now["counts"]), strict=False)
        for (label, k_shown), (_, k_now) in pairs:
            interval = wilson(int(k_shown), n_readme, Z95)
            problems.append(proportion_problem(f"outcome {label}", interval,
                                               int(k_now) / n_run, n_run))
    return [p for p in problems if p]


def _pairs(counts: str) -> list[tuple[str, str]]:
    return [tuple(item.split()) for item in counts.split(", ")]


def stats_problems(shown: list[str], now: list[str], n_readme: int, n_run: int) -> list[str]:
    """What differs between a README output at ``n_readme`` draws and a run at ``n_run``
    beyond what sampling explains (the rule is in the module docstring)."""
    if len(shown) != len(now):
        return [f"{len(now)} lines printed, the README shows {len(shown)}"]
    problems, rows = [], {}
    for a, b in zip(shown, now, strict=True):
        kind_a, kind_b = classify(a), classify(b)
        if kind_a is None or kind_b is None or kind_a[0] != kind_b[0]:
            if a != b:
                problems.append(f"line differs: README {a!r}, now {b!r}")
            continue
        pair = rows.setdefault(kind_a[0], ([], []))
        pair[0].append((row_key(kind_a[1]), kind_a[1], a))
        pair[1].append((row_key(kind_b[1]), kind_b[1], b))
    for name, (shown_rows, now_rows) in rows.items():
        if Counter(r[0] for r in shown_rows) != Counter(r[0] for r in now_rows):
            problems.append(f"{name}: keys {sorted(r[0] for r in now_rows)}, the README "
                            f"shows {sorted(r[0] for r in shown_rows)}")
            continue
        by_key = {key: (groups, line) for key, groups, line in now_rows}
        for key, groups, line in shown_rows:  # paired by key: a table may reorder its rows
            now_groups, now_line = by_key[key]
            if mask(line) != mask(now_line):
                problems.append(f"line differs beyond its numbers: README {line!r}, now "
                                f"{now_line!r}")
            problems += number_problems(name, groups, now_groups, n_readme, n_run)
    return problems


def _samples(command: str) -> int | None:
    match = re.search(r"--samples[ =](\d+)", command)
    return int(match.group(1)) if match else None


def _copy_inputs(command: str, scratch: Path) -> None:
    """Copy the repository files a command names (not outputs under out/) into scratch."""
    for word in shlex.split(command):
        source = ROOT / word
        if not word.startswith(("out/", "/")) and source.is_file():
            (scratch / word).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(source, scratch / word)


def _diff(shown: list[str], now: list[str]) -> str:
    return "\n".join(difflib.unified_diff(shown, now, "README", "now", lineterm=""))


def _durations(lines: list[str]) -> list[str]:
    """The lines with durations (``in 4003 ms``, ``in 2.5 s``) as ``in # ms``: the one
    machine-dependent number an exact block may print."""
    return [_DURATION.sub(r"in # \g<unit>", line) for line in lines]


def _run(command: str, scratch: Path, env: dict) -> tuple[subprocess.CompletedProcess, dict]:
    """Run a shell command in scratch; the process and the files it wrote (path -> bytes)."""
    before = readme.snapshot(scratch)
    done = subprocess.run(["bash", "-c", command], cwd=scratch, env=env, text=True,
                          capture_output=True, timeout=900)
    after = readme.snapshot(scratch)
    return done, {p.relative_to(scratch).as_posix(): p.read_bytes()
                  for p, stamp in after.items() if before.get(p) != stamp}


def _prerequisites(block, scratch: Path, env: dict, page: Page = README_PAGE) -> list[str]:
    """Make the out/tour/ files the block reads but earlier blocks write (``rank`` on what the
    tour's ``plan`` wrote): run those commands (once per pytest run, their files cached) in
    scratch, output not compared. The problems found."""
    first = page.first[block.index]
    written: list[str] = []
    needed = []
    for step in block.steps:
        targets = readme.command_targets(step.command)
        needed += [p for p in readme.tour_inputs(step.command, targets)
                   if not any(readme.covers(t, p) for t in written)]
        written += targets
    for index in readme.producers(list(page.commands), first, needed):
        command = page.commands[index]
        if command not in _MADE:
            _copy_inputs(command, scratch)
            done, _MADE[command] = _run(command, scratch, env)
            if done.returncode != 0:
                return [f"$ {command} (needed first)\nexit {done.returncode}\n"
                        f"{done.stderr[-3000:]}"]
        for relative, data in _MADE[command].items():
            (scratch / relative).parent.mkdir(parents=True, exist_ok=True)
            (scratch / relative).write_bytes(data)
    return []


def run_block(block, marker, tmp: Path, page: Page = README_PAGE) -> list[str]:
    """Run a console block's steps in a scratch folder under ``tmp``; the problems found."""
    (tmp / "bin").mkdir()
    env = readme.env_with_kinegrasp(tmp / "bin")
    scratch = tmp / "repo"
    scratch.mkdir()
    problems = _prerequisites(block, scratch, env, page)
    for step in [] if problems else block.steps:
        command, n_readme = step.command, _samples(step.command)
        statistic = marker.mode == "stats" and n_readme is not None
        if statistic:
            command = re.sub(r"--samples[ =]\d+", f"--samples {marker.samples}", command)
        _copy_inputs(command, scratch)
        done, written = _run(command, scratch, env)
        if command in page.prerequisites:  # as shown: what a later block reads
            _MADE[command] = written
        now = [line.rstrip() for line in done.stdout.rstrip("\n").splitlines()]
        shown = list(step.output)
        if done.returncode != 0:
            return [*problems, f"$ {command}\nexit {done.returncode}\n{done.stderr[-3000:]}"]
        found = (stats_problems(shown, now, n_readme, marker.samples) if statistic
                 else [] if _durations(now) == _durations(shown) else [_diff(shown, now)])
        if found:
            problems.append(f"$ {command}\n" + "\n".join(found) + "\nprinted:\n"
                            + "\n".join(now))
    return problems


def _block_cases():
    cases = []
    for block in CONSOLE:
        first = block.steps[0].command.split()[:2] if block.steps else ["empty"]
        for marker in block.markers:
            if marker.mode == "skip":
                continue
            mode = marker.mode + (str(marker.samples) if marker.samples else "")
            marks = [pytest.mark.expensive] if marker.expensive else []
            cases.append(pytest.param(block, marker, marks=marks,
                                      id=f"line{block.line}-{'-'.join(first)}-{mode}"))
    return cases


@pytest.fixture(scope="module", autouse=True)
def readme_catalog(tmp_path_factory):
    """The README's and the guides' commands import objects (``docs/palm_box.obj``, ...) into
    a catalog of this module's own, shared by its blocks (a block may use what an earlier one
    imported) and never seen by other modules' tests, which list the built-in objects alone
    whatever order the modules run in."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("KINEGRASP_HOME", str(tmp_path_factory.mktemp("readme_home")))
        yield


def test_every_console_block_has_a_marker():
    """A new console block says how it is tested (or why it is not)."""
    assert CONSOLE
    for block in CONSOLE:
        assert block.markers, (f"README.md line {block.line}: a console block without a "
                               "<!-- readme-test: exact|stats samples=N|skip reason=... -->")
        for marker in block.markers:
            if marker.mode == "stats":
                assert any(_samples(s.command) for s in block.steps), (
                    f"README.md line {marker.line}: stats marker on a block without --samples")


@pytest.mark.parametrize(("block", "marker"), _block_cases())
def test_readme_console_block(block, marker, tmp_path):
    """The block's commands print what the README shows (exactly, or within its intervals)."""
    if any(argv[:1] == ["screenshot"] for step in block.steps
           for argv in readme.kinegrasp_argvs(step.command)):
        from kinegrasp_env.toolkit.report.browser import find_chromium

        if find_chromium() is None:
            pytest.skip("kinegrasp screenshot needs chromium (Debian: apt-get install chromium)")
    problems = run_block(block, marker, tmp_path)
    assert not problems, "\n\n".join(problems)


def _shown(block, marker) -> tuple:
    """What a console block's test runs and compares: its steps and how (mode, samples)."""
    return block.steps, marker.mode, marker.samples


def _doc_block_cases():
    """The docs pages' console blocks, as README blocks are run; a block the README shows
    too (the same commands, output and marker) is run once, as the README's."""
    in_readme = {_shown(b, m) for b in README_PAGE.console for m in b.markers}
    cases = []
    for page in DOC_PAGES:
        for block in page.console:
            named = [s.command for s in block.steps if not s.command.startswith("mkdir ")]
            first = named[0].split()[:2] if named else ["empty"]
            for marker in block.markers:
                if marker.mode == "skip" or _shown(block, marker) in in_readme:
                    continue
                mode = marker.mode + (str(marker.samples) if marker.samples else "")
                marks = [pytest.mark.expensive] if marker.expensive else []
                cases.append(pytest.param(page, block, marker, marks=marks,
                                          id=f"{page.name}:{block.line}-{'-'.join(first)}-{mode}"))
    return cases


def test_every_docs_console_block_has_a_marker():
    """A console block of the documentation says how it is tested, as the README's do."""
    assert any(page.console for page in DOC_PAGES)
    for page in DOC_PAGES:
        for block in page.console:
            assert block.markers, (f"{page.name} line {block.line}: a console block without a "
                                   "<!-- readme-test: exact|stats samples=N|skip reason=... -->")


@pytest.mark.parametrize(("page", "block", "marker"), _doc_block_cases())
def test_docs_console_block(page, block, marker, tmp_path):
    """A docs page's block prints what the page shows (exactly, or within its intervals)."""
    if any(argv[:1] == ["screenshot"] for step in block.steps
           for argv in readme.kinegrasp_argvs(step.command)):
        from kinegrasp_env.toolkit.report.browser import find_chromium

        if find_chromium() is None:
            pytest.skip("kinegrasp screenshot needs chromium (Debian: apt-get install chromium)")
    problems = run_block(block, marker, tmp_path, page)
    assert not problems, "\n\n".join(problems)


def _doc_python_blocks():
    """The docs pages' Python blocks that the README does not show (those run there)."""
    in_readme = set(re.findall(r"```python\n(.*?)```", README, flags=re.S))
    return [pytest.param(code, id=f"{page.name}:{i}")
            for page in DOC_PAGES
            for i, code in enumerate(re.findall(r"```python\n(.*?)```",
                                                (ROOT / page.name).read_text(), flags=re.S))
            if code not in in_readme]


@pytest.mark.parametrize("code", _doc_python_blocks())
def test_docs_python_blocks_run(code, tmp_path, monkeypatch):
    """Each Python block of the documentation that the README does not show runs."""
    monkeypatch.chdir(tmp_path)
    exec(compile(code, "docs python block", "exec"), {"__name__": "__docs__"})


def test_stats_comparison_accepts_sampling_and_catches_drift():
    """The stats rule on the README's own outputs: a sample-size change alone passes; a
    P(FC) moved out of its interval, a changed key, a new column or line fails."""
    for block in CONSOLE:
        for step in block.steps:
            shown, n = list(step.output), _samples(step.command)
            if n is None or not any(classify(line) for line in shown):
                continue
            assert stats_problems(shown, shown, n, n) == []
            reordered = _reorder_rows(shown)  # a table's rows in another order pass
            assert stats_problems(shown, reordered, n, n) == [], reordered
            for i, line in enumerate(shown):
                match = stat_line(line)
                edits = [] if match is None else [
                    (group, f"{float(value) - 0.2:.3f}" if group == "p" else "other")
                    for group, value in match.groupdict().items()
                    if value and (group == "p" or group.startswith("k_"))]
                for group, value in edits:  # P(FC) 0.2 lower; a key renamed
                    edited = line[:match.start(group)] + value + line[match.end(group):]
                    assert stats_problems(shown, [*shown[:i], edited, *shown[i + 1:]], n, n), (
                        edited)
            assert stats_problems(shown, [line + " 1.0" for line in shown], n, n)
            assert stats_problems(shown, [*shown, "extra"], n, n)


def _reorder_rows(lines: list[str]) -> list[str]:
    """The lines with every run of statistic lines of one kind reversed (a table whose rows
    a small run ranks in another order)."""
    out: list[str] = []
    for line in lines:
        kind = classify(line)
        run = 0
        while kind and run < len(out) and classify(out[-1 - run]) \
                and classify(out[-1 - run])[0] == kind[0]:
            run += 1
        out.insert(len(out) - run, line)
    return out


def test_mask_hides_every_number_of_a_table_row():
    assert mask("   1      3v1   0.636   0.615..0.657    0.03067   2000  (95% CI 1e-3 .. -2)") \
        == "# # # #..# # # (#% CI # .. #)"
    assert mask("fig7_drill.png P(FC) spray_flask") == "fig7_drill.png P(FC) spray_flask"


def test_wilson_against_a_hand_computation():
    """10 of 10 at 95%: centre (1 + z^2/20) / (1 + z^2/10), half z sqrt(z^2/400) / (1 + z^2/10)."""
    z = Z95
    lo, hi = wilson(10, 10, z)
    assert hi == pytest.approx(1.0)
    assert lo == pytest.approx(1 / (1 + z * z / 10))


def test_every_readme_picture_exists_and_is_written_by_a_shown_command():
    """docs/images/X is written by a shown command as out/tour/X (scripts/make_readme_images.py
    copies it), or as docs/images/X by a command shown for that purpose."""
    images = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", README)
    assert len(images) >= 2
    targets = [t for c in readme.shown_commands(BLOCKS) for t in readme.command_targets(c)]
    for image in images:
        assert (ROOT / image).is_file(), image
        assert image.startswith(readme.IMAGES + "/"), f"{image} is not under docs/images/"
        tour = readme.TOUR + image[len(readme.IMAGES):]
        assert any(readme.covers(t, tour) or readme.covers(t, image) for t in targets), (
            f"no command in the README writes {tour} or {image}")


def test_readme_commands_write_only_ignored_paths_or_pictures():
    """What the README's kinegrasp commands write is ignored by git (out/, or a name the
    commands default to in the repository root), or a picture under docs/images/.
    Placeholders in capitals (``--out DIR``) are the user's choice and not checked."""
    if not (ROOT / ".git").exists() or shutil.which("git") is None:
        pytest.skip("not a git checkout")
    targets = {t for c in readme.shown_commands(BLOCKS) for t in readme.command_targets(c)}
    assert targets
    for target in sorted(targets):
        if readme.covers(readme.IMAGES, target) or re.fullmatch(r"[A-Z_]+(\.\w+)?", target):
            continue
        ignored = subprocess.run(["git", "check-ignore", "-q", "--no-index", target], cwd=ROOT)
        assert ignored.returncode == 0, f"a README command writes {target}, not ignored by git"
    for name in ("grasps.json", "ranked.csv", "ranked.csv.partial.jsonl", "convergence.png"):
        ignored = subprocess.run(["git", "check-ignore", "-q", "--no-index", name], cwd=ROOT)
        assert ignored.returncode == 0, f"{name} (a command's default output) is not ignored"


@pytest.mark.parametrize("index", range(len(re.findall(r"```python\n", README))))
def test_readme_python_blocks_run(index, tmp_path, monkeypatch, capsys):
    """Each block runs; where the README says what a block prints, it prints exactly that."""
    blocks = re.findall(r"```python\n(.*?)```\n\n(\S*)", README, flags=re.S)
    block, next_word = blocks[index]
    monkeypatch.chdir(tmp_path)
    exec(compile(block, f"README python block {index}", "exec"), {"__name__": "__readme__"})
    if next_word == "prints":
        for line in capsys.readouterr().out.splitlines():
            assert f"`{line}`" in README, line


def test_picture_script_runs_the_picture_commands_and_their_inputs():
    """scripts/make_readme_images.py picks the commands that write a wanted picture (as
    out/tour/X or docs/images/X) and, before them, those writing the out/tour/ files they
    read; not the others."""
    text = "\n".join([
        "```console",
        "$ kinegrasp plan --object drill --count 2 --out out/tour/g.json",
        "$ kinegrasp plan --object cube --count 2 --out out/tour/other.json",
        "$ kinegrasp rank out/tour/g.json --out out/tour/r.csv --report out/tour/r.html",
        "$ kinegrasp screenshot out/tour/r.html --out out/tour/r.png",
        "$ kinegrasp planar --plot docs/images/p.png",
        "$ kinegrasp planar --plot out/tour/unshown.png",
        "```"])
    blocks = readme.readme_blocks(text)
    pictures = ["docs/images/r.png", "docs/images/p.png"]
    commands = [c.split(" --out")[0] for c in readme.picture_commands(blocks, [], pictures)]
    assert commands == ["kinegrasp plan --object drill --count 2",
                        "kinegrasp rank out/tour/g.json", "kinegrasp screenshot out/tour/r.html",
                        "kinegrasp planar --plot docs/images/p.png"]
    assert readme.picture_commands(blocks, ["planar"], pictures) == [
        "kinegrasp planar --plot docs/images/p.png"]
