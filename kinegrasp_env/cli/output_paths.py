"""The files and folders a ``kinegrasp`` command reads and writes, checked before any work:
the input files its options name (:func:`input_files`), and an output's name, format and
folder (:func:`output_file`, :func:`output_folder`), each refusal a :class:`~kinegrasp_env.
cli.common.CLIError` of one line."""

from __future__ import annotations

from pathlib import Path

from kinegrasp_env.cli.common import CLIError

#: The options (argparse destinations) that name a file a command reads, by their label.
INPUT_OPTIONS = {"candidates": "the candidates file", "grasps": "--grasps",
                 "noise_spec": "--noise-spec", "page": "the page"}


def input_files(args) -> list[tuple[str, str]]:
    """(label, path) of each file ``args`` names for the command to read
    (:data:`INPUT_OPTIONS`)."""
    return [(label, value) for dest, label in INPUT_OPTIONS.items()
            if isinstance(value := getattr(args, dest, None), str) and Path(value).is_file()]


def named_path(text: str, name: str, kind: str) -> Path:
    """The path an output option names; CLIError for an empty or blank one (which would
    name the current folder)."""
    if not text.strip():
        raise CLIError(f"{name} is empty; give a {kind} name")
    return Path(text)


#: the names of the files a command writes in one format (:func:`output_file`'s ``suffixes``)
HTML_SUFFIXES = (".html", ".htm")
CSV_SUFFIXES = (".csv",)
PNG_SUFFIXES = (".png",)


def output_file(text: str, name: str, *, figure: bool | None = None,
                inputs: list[tuple[str, str]] = (), suffixes: tuple[str, ...] = ()) -> Path:
    """A file the command will write, checked before any work: a name is given, not a
    folder, not one of the files it reads (``inputs``: (label, path) pairs,
    :func:`input_files`), its folder can be written (:func:`check_parents`: missing folders
    are created only inside the current folder), for a figure (``figure``; by default when
    ``name`` is ``--plot``) a format matplotlib writes, and where the command writes one
    format (``suffixes``, lower case: e.g. ``(".html",)``) a name that says it. Nothing is
    created here."""
    path = named_path(text, name, "file")
    if path.is_dir():
        raise CLIError(f"{name} {text} is a folder; give a file name")
    for label, source in inputs:
        if path.exists() and path.samefile(source):
            raise CLIError(f"{name} {text} is {label} the command reads; give another file "
                           "name")
    if suffixes and path.suffix.lower() not in suffixes:
        raise CLIError(f"{name} {text}: give a {' or '.join(suffixes)} file (the command "
                       f"writes {suffixes[0][1:].upper()})")
    check_parents(path.parent, f"{name} {text}")
    if figure or (figure is None and name == "--plot"):
        check_figure_format(path, name)
    return path


def output_folder(text: str, name: str = "--out") -> Path:
    """A folder the command will write into (and create), checked before any work: not a
    file, and writable where it will be made (:func:`check_parents`)."""
    path = named_path(text, name, "folder")
    if path.exists() and not path.is_dir():
        raise CLIError(f"{name} {text} is a file; give a folder")
    if not path.exists():
        check_parents(path.parent, f"{name} {text}")
    else:
        check_parents(path, f"{name} {text}")
    return path


def check_parents(folder: Path, label: str) -> None:
    """CLIError (``label: ...``, one line) unless files can be written in ``folder``: it
    exists, or it lies inside the current folder (then it is created when the command
    writes, and nothing outside the current folder ever is); the nearest existing folder
    on its path is a folder; and a file can be created there (tried: a read-only mount or
    ``/proc`` refuse what permission bits would allow)."""
    import os
    import tempfile

    folder = Path(os.path.abspath(folder))  # ".." resolved, links kept
    existing = next(p for p in [folder, *folder.parents] if p.exists())
    if existing != folder and existing.is_dir():
        inside = Path(os.path.abspath(Path.cwd()))
        if not (folder.is_relative_to(inside) and existing.is_relative_to(inside)):
            missing = next(p for p in [folder, *folder.parents] if p.parent == existing)
            raise CLIError(f"{label}: folder {missing} does not exist (create it first: "
                           "only folders inside the current folder are made)")
    if not existing.is_dir():
        raise CLIError(f"{label}: {existing} is not a folder")
    try:
        tempfile.TemporaryFile(dir=existing).close()
    except OSError as exc:
        raise CLIError(f"{label}: cannot write in {existing} ({exc.strerror or exc})") from None


def check_figure_format(path: Path, name: str) -> None:
    """CLIError unless ``path``'s extension is a format matplotlib writes (png, pdf, svg...)."""
    from matplotlib.backend_bases import FigureCanvasBase

    formats = FigureCanvasBase.get_supported_filetypes()
    suffix = path.suffix.lower().lstrip(".")
    if suffix not in formats:
        raise CLIError(f"{name} {path}: {('.' + suffix) if suffix else 'no extension'} is not "
                       f"a figure format; use one of {', '.join(sorted(formats))}")


def report_path(text: str | None, name: str = "--report",
                inputs: list[tuple[str, str]] = ()) -> Path | None:
    """A validated ``--report`` file (an HTML page, not one of ``inputs``:
    :func:`output_file`), or None when not asked for."""
    return None if text is None else output_file(text, name, inputs=inputs,
                                                 suffixes=HTML_SUFFIXES)
