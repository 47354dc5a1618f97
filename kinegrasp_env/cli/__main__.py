"""``python -m kinegrasp_env.cli`` runs the ``kinegrasp`` command."""

from kinegrasp_env.cli.main import run

run()
