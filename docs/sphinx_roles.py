"""The docstrings' Sphinx roles as cross-references of the site.

The package's docstrings name other objects with Sphinx roles (``:func:`~a.b.f```,
``:class:`Engine```, ``:mod:`a.b```, ``:meth:``, ``:data:``, ``:attr:``, ...), which
mkdocstrings would show as they are written. ``SphinxRoles`` is a griffe extension, registered
in mkdocs.yml under the python handler's ``extensions:``: once griffe has read the package, and
before mkdocstrings renders anything, it rewrites every docstring's roles to Markdown:

* a role whose target the API pages render becomes a mkdocs-autorefs cross-reference,
  ``[`f`][a.b.f]``, to the object's anchor;
* any other (an object no page renders: a private one, a module without a page, a member
  with no docstring; a name outside the package; ``!target``) becomes inline code of the
  displayed name, ``f``: no broken link, no autorefs warning under ``mkdocs build --strict``.

The displayed name follows Sphinx: the target as written, its last component only after a
``~``, the title of ``title <target>``. Targets are looked up as Sphinx's Python domain does:
relative to the docstring's class (and the classes around it) and module first, then to the
rooms the module is in (the names a room's ``__init__`` exports), then as an absolute path;
``.name`` also matches any object of the package whose path ends with it, when only one does.
Imports are followed (a name a module imports resolves to where it is defined), and so are the
rooms' lazy export tables (``kinegrasp_env.quality.ferrari_canny`` is
``kinegrasp_env.quality.epsilon.ferrari_canny``).

What the pages render comes from ``api_layout.py`` (the ``::: identifier`` blocks
``gen_api.py`` writes) and mkdocstrings' options in mkdocs.yml: each block's object and,
unless the block says ``members: false``, its members that mkdocstrings shows (public, not
imported, with a docstring of their own or in a member; not a module's submodules).

``gen_api.py`` and ``gen_benchmarks.py`` run the same rewrite over the docstring text they
copy into their pages (``References.load().markdown``).
"""

from __future__ import annotations

import functools
import re
import sys
from pathlib import Path

import griffe

DOCS = Path(__file__).resolve().parent
if str(DOCS) not in sys.path:  # the docs tooling's modules, beside this one
    sys.path.insert(0, str(DOCS))

import api_layout  # noqa: E402

#: A role: ``:func:`target```, ``:py:meth:`~a.b.C.m```, ``:class:`title <a.b.C>```.
ROLE = re.compile(r":(?:py:)?(?P<role>func|class|mod|meth|data|attr|exc|obj|const|type)"
                  r":`(?P<content>[^`]+)`")
#: Fenced code blocks: left as written.
FENCE = re.compile(r"^[ \t]*(```|~~~).*?^[ \t]*\1[^\n]*$", re.MULTILINE | re.DOTALL)
EXPLICIT = re.compile(r"(?P<title>.*?)\s*<(?P<target>[^<>]+)>", re.DOTALL)


class References:
    """The package as griffe read it, and the anchors of the objects the API pages render."""

    def __init__(self, package: griffe.Module, directives: dict[str, bool],
                 public: dict[str, str]) -> None:
        self.package = package
        #: Public path -> defining path, for the rooms' lazy exports.
        self.public = public
        #: The packages with exports (the rooms; for lookups relative to a room's modules).
        self.rooms = {path.rsplit(".", 1)[0] for path in public}
        #: Canonical path of each rendered object -> the anchor (identifier) of its heading.
        self.anchors: dict[str, str] = {}
        for identifier, members in directives.items():
            obj = self.find(identifier)
            if obj is None:
                continue
            self.anchors[obj.path] = identifier
            if members:
                self._add_members(obj, identifier)

    @classmethod
    def from_layout(cls, package: griffe.Module) -> References:
        return cls(package, api_layout.directives(), api_layout.public_paths())

    @classmethod
    def load(cls) -> References:
        """The references of the package read afresh by griffe (for the page generators,
        which copy docstring text outside mkdocstrings; under a second)."""
        package = griffe.load(api_layout.PACKAGE, search_paths=[str(DOCS.parent)])
        return cls.from_layout(package)

    def _add_members(self, obj: griffe.Object, anchor: str) -> None:
        """The members mkdocstrings renders under ``obj`` (filters ``!^_``, no undocumented
        member, no inherited or imported one, no submodule)."""
        if not (obj.is_class or obj.is_module):
            return
        for name, member in obj.members.items():
            if member.is_alias or name.startswith("_") or (obj.is_module and member.is_module):
                continue
            try:
                documented = member.has_docstrings
            except griffe.AliasResolutionError:
                documented = False
            if documented:
                self.anchors[member.path] = f"{anchor}.{name}"
                self._add_members(member, f"{anchor}.{name}")

    def find(self, path: str, _depth: int = 0) -> griffe.Object | None:
        """The object at dotted ``path`` in the package, following imports and lazy exports
        (None when there is none, or it lies outside the package). A submodule comes before a
        lazy export of the same name (``kinegrasp_env.cli.main``: the module)."""
        parts = path.split(".")
        if _depth > 16 or parts[0] != self.package.name or not all(parts):
            return None
        return self._walk(self.package, parts[1:], _depth)

    def _walk(self, obj: griffe.Object, parts: list[str], depth: int) -> griffe.Object | None:
        if not parts:
            return obj
        part, rest = parts[0], parts[1:]
        member, found = obj.members.get(part), None
        if member is not None and member.is_alias:
            found = self.find(".".join([member.target_path, *rest]), depth + 1)
        elif member is not None:
            found = self._walk(member, rest, depth)
        here = f"{obj.path}.{part}"
        if found is None and here in self.public:
            found = self.find(".".join([self.public[here], *rest]), depth + 1)
        return found

    @functools.cached_property
    def _paths(self) -> list[str]:
        found, stack = [], [self.package]
        while stack:
            obj = stack.pop()
            found.append(obj.path)
            stack.extend(m for m in obj.members.values() if not m.is_alias)
        return found

    def resolve(self, target: str, scope: griffe.Object | None,
                specific: bool = False) -> griffe.Object | None:
        """The object ``target`` names in a docstring of ``scope`` (see the module's
        docstring for the order), or None."""
        candidates = []
        node = scope
        while node is not None:
            if node.is_class or node.is_module:
                candidates.append(f"{node.path}.{target}")
            if node.is_module:
                parts = node.path.split(".")
                candidates += [f"{room}.{target}" for n in range(len(parts) - 1, 1, -1)
                               if (room := ".".join(parts[:n])) in self.rooms]
                break
            node = node.parent
        candidates.append(target)
        for candidate in candidates:
            obj = self.find(candidate)
            if obj is not None:
                return obj
        if specific:
            matches = [p for p in self._paths if p.endswith(f".{target}")]
            if len(matches) == 1:
                return self.find(matches[0])
        return None

    def anchor(self, target: str, scope: griffe.Object | None = None,
               specific: bool = False) -> str | None:
        """The anchor of the rendered object ``target`` names, or None."""
        obj = self.resolve(target, scope, specific)
        return None if obj is None else self.anchors.get(obj.path)

    def role(self, content: str, scope: griffe.Object | None = None) -> str:
        """The Markdown for one role's content (the text between its backticks)."""
        explicit = EXPLICIT.fullmatch(content.strip())
        if explicit:
            title = " ".join(explicit["title"].split())
            target = "".join(explicit["target"].split())
        else:
            title, target = None, "".join(content.split())  # a wrapped target: no spaces
        link = not target.startswith("!")
        target = target.removeprefix("!")
        short = target.startswith("~")
        target = target.removeprefix("~")
        specific = target.startswith(".")
        target = target.removeprefix(".")
        if not title:
            title = target.rsplit(".", 1)[-1] if short else target
        anchor = self.anchor(target.removesuffix("()"), scope, specific) if link else None
        return f"[`{title}`][{anchor}]" if anchor else f"`{title}`"

    def markdown(self, text: str, scope: griffe.Object | None = None) -> str:
        """``text`` with every role outside fenced code blocks rewritten (see ``role``)."""
        out, start = [], 0
        for fence in FENCE.finditer(text):
            out += [self._roles(text[start:fence.start()], scope), fence.group()]
            start = fence.end()
        out.append(self._roles(text[start:], scope))
        return "".join(out)

    def _roles(self, text: str, scope: griffe.Object | None) -> str:
        return ROLE.sub(lambda m: self.role(m["content"], scope), text)


def documented(obj: griffe.Object):
    """``obj`` and every object under it, aliases (imports) aside."""
    yield obj
    for member in obj.members.values():
        if not member.is_alias:
            yield from documented(member)


class SphinxRoles(griffe.Extension):
    """Rewrite the roles of every docstring of the package once griffe has read it all."""

    def on_package(self, *, pkg: griffe.Module, loader: griffe.GriffeLoader,
                   **kwargs) -> None:
        if pkg.name != api_layout.PACKAGE:
            return
        references = References.from_layout(pkg)
        for obj in documented(pkg):
            if obj.docstring is not None:
                obj.docstring.value = references.markdown(obj.docstring.value, obj)
