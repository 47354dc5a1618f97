"""The default robot's catalog name (the paper's KUKA LBR iiwa with the SDH-like hand), in a
module of its own so that the command line can name it without loading the catalog."""

from __future__ import annotations

#: The robot every command, grasp file and environment takes when none is named.
DEFAULT_ROBOT = "kuka_sdh"
