"""The ``kinegrasp`` command line: ``main`` (the console script's entry point) in ``main``, one
module per command group (``arms``, ``grasping``, ``toolkit``), shared helpers in ``common``.
"""

from kinegrasp_env.cli.main import main

__all__ = ["main"]
