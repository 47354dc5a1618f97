"""The README's promises: its pictures come from commands it shows, its Python runs."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def _console_commands() -> list[str]:
    """Commands of the ```console blocks (``$ `` lines, continuation lines joined)."""
    commands = []
    for block in re.findall(r"```console\n(.*?)```", README, flags=re.S):
        current = None
        for line in block.splitlines():
            if line.startswith("$ "):
                current = line[2:]
            elif current is not None and line.startswith("      "):
                current += " " + line.strip()
            else:
                if current is not None:
                    commands.append(current.replace("\\ ", " "))
                current = None
        if current is not None:
            commands.append(current.replace("\\ ", " "))
    return commands


def test_every_readme_picture_exists_and_is_written_by_a_shown_command():
    images = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", README)
    assert len(images) >= 2
    commands = _console_commands()
    for image in images:
        assert (ROOT / image).is_file(), image
        producers = [c for c in commands if c.startswith("kinegrasp ")
                     and any(image == target or image.startswith(target.rstrip("/") + "/")
                             for target in re.findall(r"--(?:plot|out) (\S+)", c))]
        assert producers, f"no command in the README writes {image}"


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
