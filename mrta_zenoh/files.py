"""Writing output files whole or not at all (a plot, a summary): write beside, then rename."""

from __future__ import annotations

from pathlib import Path
from typing import Callable

from .errors import ConfigError


def _atomic(output: Path, write: Callable[[Path], None]) -> None:
    output = Path(output)
    tmp = output.with_name(output.name + ".tmp")
    try:
        write(tmp)
        tmp.replace(output)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise ConfigError(f"cannot write: {exc.strerror}", file=str(output)) from None


def save_figure(fig, output: Path) -> None:
    """A matplotlib figure to `output` as PNG, atomically; ConfigError if it cannot be written."""
    _atomic(output, lambda tmp: fig.savefig(tmp, format="png"))


def write_text(output: Path, text: str) -> None:
    _atomic(output, lambda tmp: tmp.write_text(text, encoding="utf-8"))
