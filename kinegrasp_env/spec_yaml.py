"""The YAML reader of the files a user writes (robot descriptions, noise specs, sweep specs):
YAML 1.2's numbers (``1e-2`` is a number, as YAML 1.1 would not read it) and a key given twice
in one mapping refused (plain YAML keeps the last without a word)."""

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
