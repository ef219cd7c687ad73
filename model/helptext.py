"""The command line's help layout, shared by every subcommand's parser (model.cli and the parsers of
model.verify and model.studies): descriptions and epilogs as written (examples and exit codes keep their
lines), and every option's default shown after its help unless the help already says it, or the default is
None, False, empty or the option is required."""

from __future__ import annotations

import argparse


class Formatter(argparse.RawDescriptionHelpFormatter):
    """argparse's raw-description layout with the defaults shown (module docstring)."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        default = action.default
        if ("default" in text.lower() or not action.option_strings or action.required
                or default is None or default is False or default is argparse.SUPPRESS
                or (isinstance(default, (list, tuple, dict, str)) and not default)):
            return text
        return f"{text} (default: %(default)s)" if text else "(default: %(default)s)"


__all__ = ["Formatter"]
