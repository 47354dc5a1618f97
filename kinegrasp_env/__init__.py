"""kinegrasp: grasp quality under kinematic (joint-angle) noise.

Importing the package registers its Gymnasium environments (see ``ENV_IDS``).
"""

from __future__ import annotations

__version__ = "0.1.0"
__all__ = ["__version__"]
