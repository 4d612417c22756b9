"""autosar: navigation-aided automotive SAR, from drive logs to centimetre-accurate radar maps."""

from __future__ import annotations

__version__ = "0.1.0"

from autosar_cli.config import Config, ConfigError, load_config  # noqa: E402

__all__ = ["Config", "ConfigError", "load_config", "__version__"]
