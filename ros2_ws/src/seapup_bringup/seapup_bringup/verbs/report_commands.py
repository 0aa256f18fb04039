"""``./seapup report``: the thesis's targets scored against runs of this code -- ``report.json`` and one HTML page.

Every target of the targets file (:mod:`seapup_runs.targets`, optionally only some chapters) is scored
against the run that produces ours (:mod:`seapup_bringup.report.reproduction`: each run cached by its
description and the code version, several in parallel with ``--jobs``). ``report.json`` holds the
commit, the counts per chapter and pooled, every target's row and how the page was made;
``report.html`` is drawn from that same document -- a summary per chapter with the largest misses, per
chapter the thesis's numbers beside ours (difference, tolerance and its reason, status in colour) and
our analogues of the thesis's figures, the deviation register and the typos we read around, and how
the page was made -- self-contained (inline CSS, PNG figures embedded; nothing fetched).
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import sys
import time
from pathlib import Path

from seapup_bringup.output import add_json_argument, emit_json, progress, text_stream
from seapup_bringup.report.page import build_document, commit, provenance, update_readme, write_page

__all__ = ["report_command", "report_parser"]


# -- the command ------------------------------------------------------------------------------------------------
def report_parser() -> argparse.ArgumentParser:
    """The parser of ``./seapup report`` (its usage line in ``./seapup help`` is generated from it)."""
    parser = argparse.ArgumentParser(prog="./seapup report", description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("runs") / "report", help="output directory (default runs/report)")
    parser.add_argument("--chapters", help="only these chapters, comma separated (3, 4, 5, 6, 7, A)")
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="runs in parallel processes")
    parser.add_argument("--cache", type=Path, help="run cache directory (default $SEAPUP_CACHE or ~/.cache/seapup/runs)")
    parser.add_argument("--no-cache", action="store_true", help="rerun everything (the cache is refreshed)")
    parser.add_argument("--targets", type=Path, help="a targets file other than the product's (to check an edit)")
    parser.add_argument("--readme", type=Path, help="rewrite this README's generated score table (whole report only)")
    add_json_argument(parser)
    return parser


def report_command(argv: list[str]) -> int:
    """``./seapup report``: score every thesis target against runs flown now or taken from the cache; write the page."""
    parser = report_parser()
    args = parser.parse_args(argv)
    text = text_stream(args)
    from seapup_bringup.report.reproduction import code_version, default_cache, run_all
    from seapup_runs.targets import CHAPTERS, TargetsError, load_targets, runs_of, score_all, summarise
    if args.jobs < 1:
        parser.error("--jobs must be at least 1")
    chapters = None
    if args.chapters:
        chapters = [c.strip() for c in args.chapters.split(",") if c.strip()]
        unknown = [c for c in chapters if c not in CHAPTERS]
        if unknown or not chapters:
            parser.error(f"--chapters: unknown {', '.join(unknown) or '(none given)'}; known: {', '.join(CHAPTERS)}")
    try:
        targets = load_targets(args.targets)
        descriptions = runs_of(args.targets)
    except TargetsError as exc:
        print(f"seapup: error: {exc}", file=sys.stderr)
        return 1
    if chapters is not None:
        targets = [t for t in targets if t.chapter in chapters]
    if not targets:
        print("seapup: error: no targets in the chapters asked for", file=sys.stderr)
        return 1
    if args.readme is not None and (chapters is not None or args.targets is not None):
        parser.error("--readme takes the whole report of the product's targets (no --chapters, no --targets)")
    needed = {name: descriptions[name] for name in dict.fromkeys(run for t in targets for run in t.runs)}
    if chapters is None and "vehicles" in descriptions:   # the whole report: the two vehicles side by side too
        needed["vehicles"] = descriptions["vehicles"]
    wall, cpu = time.perf_counter(), time.process_time()
    print(f"report: {len(targets)} targets, {len(needed)} runs, {args.jobs} parallel", file=text, flush=True)
    payloads = run_all(needed, args.cache or default_cache(), jobs=args.jobs, use_cache=not args.no_cache,
                       progress=lambda f: progress("report", f))
    results = {name: (p["result"] if p["result"] is not None else {}) for name, p in payloads.items()}
    scores = score_all(targets, results)
    made = {"argv": list(argv), "commit": commit(), "date": datetime.datetime.now(datetime.timezone.utc)
            .strftime("%Y-%m-%d %H:%M UTC"), "code_version": code_version(), "jobs": args.jobs,
            "machine": f"{platform.node()}, {platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}",
            "wall_s": time.perf_counter() - wall, "cpu_s": time.process_time() - cpu,
            "targets_file": str(args.targets or "seapup_runs/data/thesis_targets.yaml")}
    document = build_document(scores, summarise(scores), payloads, needed, made)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "report.json").write_text(json.dumps(document, indent=1))
    page = write_page(document, args.out / "report.html")
    for ch, c in list(document["chapters"].items()) + [("pooled", document["pooled"])]:
        print(f"  {('ch. ' + ch) if ch != 'pooled' else 'pooled':8} {c['reproduced']:4d} of {c['asked']:4d} reproduced, "
              f"{c['deviations']} deviations, {c['failed']} failed, {c['not_run']} not run", file=text)
    for run in document["runs"]:
        if run["error"]:
            print(f"  run {run['name']} failed: {run['error']}", file=text)
    print(f"  runs: {provenance(document['runs'])}", file=text)
    print(f"wrote {page} and {args.out / 'report.json'} ({made['wall_s']:.1f} s)", file=text)
    if args.readme is not None:
        try:
            changed = update_readme(args.readme, document)
        except (OSError, ValueError) as exc:
            print(f"seapup: error: {exc}", file=sys.stderr)
            return 1
        print(f"{args.readme}: score table {'updated' if changed else 'unchanged'}", file=text)
    emit_json(args, document)
    return 0
