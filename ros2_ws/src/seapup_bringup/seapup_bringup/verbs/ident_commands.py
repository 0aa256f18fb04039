"""``./seapup ident``: identification experiments and fits from bags or CSV files (thesis ch. 6).

The subcommands and what they do are :mod:`seapup_bringup.graph.identification`'s; this verb parses the
arguments, prints what it is doing and writes the result as JSON with ``--json``.
"""
from __future__ import annotations

from seapup_bringup.graph.identification import handle, ident_parser
from seapup_bringup.output import emit_json, text_stream

__all__ = ["main", "ident_parser"]


def main(argv=None) -> int:
    """``./seapup ident``: 0, or 1 with the reason in one line."""
    from seapup_bringup.graph.sil import SilError
    parser = ident_parser()
    args = parser.parse_args(argv)
    text = text_stream(args)
    try:
        result = handle(args, text)
    except (ValueError, OSError, SilError) as exc:  # one line, never a traceback
        print(f"seapup ident {args.command}: error: {exc}", file=text)
        return 1
    emit_json(args, result)
    return 0
