"""How a page's command line spells the options it was made with (every setting spelled
out, the defaults included where they change a number)."""

from __future__ import annotations

from kinegrasp_env.cli.common import DEFAULT_FRICTION


def friction_words(args) -> list[str]:
    """``--friction MU`` as a page's command line spells it (nothing at the default)."""
    text = getattr(args, "friction", None)
    return [] if text is None or float(text) == DEFAULT_FRICTION else ["--friction", str(text)]


def sigma_words(sigma) -> str:
    """A run's joint sigma as text (one number, or 7 separated by spaces)."""
    return f"{sigma:g}" if isinstance(sigma, float) else " ".join(f"{s:g}" for s in sigma)


def noise_words(args, sigma_text: str) -> list[str]:
    """A page command's noise options: ``--noise-spec F``, or ``--sigma S --noise K``."""
    if getattr(args, "noise_spec", None):
        return ["--noise-spec", str(args.noise_spec)]
    return ["--sigma", sigma_text, "--noise", args.noise]
