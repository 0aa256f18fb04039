"""``./seapup campaign SPEC.yaml``: a Monte Carlo campaign on Dask, its table and its page (issue 26).

The campaign is flown by :func:`seapup_bringup.campaign_runner.run_campaign` (a LocalCluster of ``--workers``
processes, or an existing cluster with ``--scheduler``; ``--resume`` keeps the finished tasks); this verb checks
the options, loads the campaign file and prints where the table and page went (docs/campaigns.md).
"""
from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

from seapup_bringup.campaign_runner import run_campaign, ship_missions
from seapup_bringup.output import add_json_argument, emit_json, text_stream

__all__ = ["campaign_command"]


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="./seapup campaign", description=__doc__.split("\n\n")[0])
    p.add_argument("spec", type=Path, help="the campaign file (YAML; see docs/campaigns.md) or a shipped "
                   "campaign's name (controller-robustness, adaptive-500, demo-mission-robustness)")
    p.add_argument("--scheduler", help="address of an existing Dask scheduler (default: a LocalCluster here)")
    p.add_argument("--connect-timeout", type=float, default=30.0, metavar="S",
                   help="seconds to keep trying to reach --scheduler (default 30)")
    p.add_argument("--workers", type=int, default=None, help="LocalCluster worker processes (default: the CPUs)")
    p.add_argument("--out", type=Path, default=None, help="output directory (default runs/campaigns/NAME)")
    p.add_argument("--resume", action="store_true", help="keep the finished tasks of an interrupted campaign")
    p.add_argument("--limit", type=int, default=None, help="fly only the first N runs (a trial of the file)")
    add_json_argument(p)
    return p


def campaign_command(argv: list[str]) -> int:
    """``./seapup campaign``: see the module docstring."""
    from seapup_runs.campaign import CampaignError, load_campaign
    args = _parser().parse_args(argv)
    text = text_stream(args)
    if args.workers is not None and args.workers < 1:
        print("seapup: error: --workers must be >= 1", file=sys.stderr)
        return 2
    if args.limit is not None and args.limit < 1:
        print("seapup: error: --limit must be >= 1", file=sys.stderr)
        return 2
    if not math.isfinite(args.connect_timeout) or args.connect_timeout <= 0:
        print(f"seapup: error: --connect-timeout must be a positive number of seconds, got {args.connect_timeout}",
              file=sys.stderr)
        return 2
    try:
        ship_missions()
        campaign = load_campaign(args.spec)
    except CampaignError as exc:
        print(f"seapup: error: {exc}", file=sys.stderr)
        return 1
    out = args.out or Path(os.environ.get("SEAPUP_ROOT", ".")) / "runs" / "campaigns" / campaign.name
    try:
        summary = run_campaign(campaign, out, scheduler=args.scheduler, workers=args.workers, resume=args.resume,
                               limit=args.limit, text=text, connect_timeout=args.connect_timeout)
    except CampaignError as exc:
        print(f"seapup: error: {exc}", file=sys.stderr)
        return 1
    emit_json(args, summary)
    return 0 if summary["runs"] else 1
