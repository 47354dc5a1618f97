"""``python -m kinegrasp_env.cli`` runs the ``kinegrasp`` command."""

import sys

from kinegrasp_env.cli import main

sys.exit(main())
