"""The reader of the files a user writes (robot descriptions, noise specs, sweep specs, grasp
and palm-pose files): their text (:func:`read_user_text`: a missing file, a folder or a binary
file is one line), JSON (:func:`parse_json`) and YAML (:func:`read_spec`) with YAML 1.2's
numbers (``1e-2`` is a number, as YAML 1.1 would not read it) and a key given twice in one
mapping refused (plain YAML keeps the last without a word)."""

from __future__ import annotations

import re

#: Numbers YAML 1.1 reads as strings but YAML 1.2 as floats (``1e-2``, ``5E3``).
_EXPONENT_FLOAT = re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$")


def spec_loader() -> type:
    """``yaml.SafeLoader`` that reads ``1e-2`` as a number (YAML 1.1 would read a string) and
    refuses a key given twice in one mapping (plain YAML keeps the last silently); merge
    keys (``<<: *base``) are read as YAML reads them, an explicit key overriding a merged
    one."""
    import yaml

    class SpecLoader(yaml.SafeLoader):
        def construct_mapping(self, node, deep=False):
            seen = set()
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":  # "<<: *base": may be overridden
                    continue
                key = self.construct_object(key_node, deep=True)
                if key in seen:
                    raise yaml.constructor.ConstructorError(
                        None, None, f"key {key!r} appears twice", key_node.start_mark)
                seen.add(key)
            return super().construct_mapping(node, deep)

    SpecLoader.add_implicit_resolver("tag:yaml.org,2002:float", _EXPONENT_FLOAT,
                                     list("-+0123456789."))
    return SpecLoader


def read_user_text(path) -> str:
    """The text of a file a user names; ValueError (one line naming the file) where there is
    none, it is a folder, or it is not text (a mesh given for a spec)."""
    from pathlib import Path

    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{path}: is a folder, not a file")
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ValueError(f"{path}: no such file") from None
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not a text file ({exc.reason} at byte {exc.start})") \
            from None
    except OSError as exc:
        raise ValueError(f"{path}: cannot be read ({exc.strerror or exc})") from None


def read_spec(path) -> object:
    """The parsed content of a user's YAML file, or JSON by its ``.json`` suffix, read with
    :func:`spec_loader`; ValueError (one line: file, line, column, what) for a file that
    cannot be read (:func:`read_user_text`) or does not parse."""
    from pathlib import Path

    import yaml

    path = Path(path)
    text = read_user_text(path)
    if path.suffix.lower() == ".json":
        return parse_json(text, path)
    try:
        return yaml.load(text, Loader=spec_loader())  # a SafeLoader
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f"{path}:{mark.line + 1}:{mark.column + 1}" if mark else str(path)
        raise ValueError(f"{where}: not valid YAML: "
                         f"{exc.problem or exc.context or 'syntax error'}") from None
    except yaml.YAMLError as exc:
        raise ValueError(f"{path}: not valid YAML: {' '.join(str(exc).split())}") from None


def parse_json(text: str, path) -> object:
    """The JSON of a user's file ``path`` (its ``text``); ValueError (one line: file, line,
    column, what) where it does not parse."""
    import json

    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}:{exc.lineno}:{exc.colno}: not valid JSON: {exc.msg}") \
            from None
