"""The reproduction report's document and page: the thesis's targets scored against runs of this code
(:mod:`seapup_bringup.report.reproduction` flies the runs) -- ``report.json`` and one HTML page.

``report.json`` holds the commit, the counts per chapter and pooled, every target's row and how the page was
made; ``report.html`` is drawn from that same document -- a summary per chapter with the largest misses, per
chapter the thesis's numbers beside ours (difference, tolerance and its reason, status in colour) and our
analogues of the thesis's figures, the deviation register and the typos we read around, and how the page was
made -- self-contained (inline CSS, PNG figures embedded; nothing fetched). ``./seapup report``
(:mod:`seapup_bringup.verbs.report_commands`) writes both.
"""
from __future__ import annotations

import math
import os
import subprocess
from pathlib import Path

from seapup_runs.pages import CSS as _CSS, esc as _e, figure as _figure, fmt as _fmt
from seapup_runs.targets import CAUSE_CLASSES

__all__ = ["build_document", "write_page", "provenance", "readme_block", "update_readme", "commit", "CHAPTER_TITLES"]

CHAPTER_TITLES = {"3": "The open-loop model (ch. 3)", "4": "Self-test identification (ch. 4)",
                  "5": "The self-test and the closed loop (ch. 5)", "6": "Identification (ch. 6)",
                  "7": "Adaptive autopilots (ch. 7)", "A": "Trials of the vehicle (App. A)"}
_STATUS_TEXT = {"reproduced": "reproduced", "deviation": "deviation", "failed": "failed", "not_run": "not run"}


def commit() -> str:
    """The source tree's ``git describe`` (or ``$SEAPUP_COMMIT``, or unknown)."""
    root = Path(__file__).resolve()
    for parent in root.parents:  # the source tree, or the install's origin (colcon symlinks into it)
        if (parent / ".git").exists():
            try:
                out = subprocess.run(["git", "-C", str(parent), "describe", "--always", "--dirty"],
                                     capture_output=True, text=True, timeout=10)
                if out.returncode == 0:
                    return out.stdout.strip()
            except (OSError, subprocess.SubprocessError):
                pass
    return os.environ.get("SEAPUP_COMMIT", "unknown")


def _misses_by_size(rows: list[dict]) -> list[dict]:
    """The missed targets, largest first: how many tolerance half-widths ours lies from the thesis (statements and
    targets with no value of ours after the numbers)."""
    out = []
    for row in rows:
        if row["status"] not in ("failed", "deviation"):
            continue
        size = math.inf
        if isinstance(row["ours"], (int, float)) and not isinstance(row["ours"], bool) and row["low"] is not None \
                and row["high"] is not None and row["high"] > row["low"]:  # an exact target has no band to count in
            size = abs(row["ours"] - row["thesis"]) / ((row["high"] - row["low"]) / 2.0)
        out.append({"id": row["id"], "where": row["where"], "quantity": row["quantity"], "status": row["status"],
                    "tolerances_away": size if math.isfinite(size) else None})
    # numbers first, furthest first; then the statements and targets without a value (no distance to rank by)
    return sorted(out, key=lambda m: (m["tolerances_away"] is None, -(m["tolerances_away"] or 0.0)))


def build_document(scores, totals: dict, payloads: dict, descriptions: dict, made: dict) -> dict:
    """``report.json``: commit, counts per chapter and pooled, the targets' rows, the runs, how it was made."""
    rows = [s.row() for s in scores]
    def counts(c):
        return {k: c[k] for k in ("asked", "reproduced", "deviations", "failed", "not_run", "by_class")}
    return {"commit": made["commit"], "date": made["date"],
            "chapters": {ch: {**counts(c), "misses": c["misses"]} for ch, c in totals["chapters"].items()},
            "pooled": {**counts(totals["pooled"]), "misses": totals["pooled"]["misses"]},
            "largest_misses": _misses_by_size(rows)[:10],
            "targets": rows,
            "runs": [{"name": name, "kind": descriptions[name]["kind"], "doc": descriptions[name].get("doc", ""),
                      "directory": p["directory"], "cached": p.get("cached", False), "wall_s": p.get("wall_s"), "cpu_s": p.get("cpu_s"),
                      "error": p.get("error"), "figures": [{**f, "path": str(Path(p["directory"]) / f["file"])}
                                                           for f in p.get("figures", [])]}
                     for name, p in payloads.items()],
            # the two vehicles side by side (no thesis target: the claim tried on a second ROV)
            "vehicles": ((payloads.get("vehicles") or {}).get("result") or {}).get("vehicles"),
            "made": made}


# -- the page ---------------------------------------------------------------------------------------------------
def _bar(c: dict) -> str:
    asked = max(c["asked"], 1)
    parts = [("", c["reproduced"]), ("dev", c["deviations"]), ("fail", c["failed"]), ("nr", c["not_run"])]
    return "".join(f'<span class="bar {cls}" style="width:{160 * n / asked:.1f}px"></span>' for cls, n in parts if n)


def _summary_rows(document: dict) -> str:
    out = []
    for ch, c in list(document["chapters"].items()) + [("pooled", document["pooled"])]:
        title = CHAPTER_TITLES.get(ch, ch) if ch != "pooled" else "pooled"
        link = f'<a href="#chapter-{_e(ch)}">{_e(title)}</a>' if ch != "pooled" else "<b>pooled</b>"
        share = 100.0 * c["reproduced"] / c["asked"] if c["asked"] else 0.0
        out.append(f"<tr><td>{link}</td><td class=num>{c['asked']}</td><td class=num>{c['reproduced']}</td>"
                   f"<td class=num>{share:.0f} %</td><td class=num>{c['deviations']}</td><td class=num>{c['failed']}</td>"
                   f"<td class=num>{c['not_run']}</td><td>{_bar(c)}</td></tr>")
    return "".join(out)


def _target_rows(rows: list[dict]) -> str:
    out = []
    for r in rows:
        notes = []
        if r["deviation"]:
            notes.append(f'deviation: {_e(r["deviation"]["reason"])} (<code>{_e(r["deviation"]["doc"])}</code>)')
        if r["typo"]:
            notes.append(f'read: {_e(r["typo"]["read"])}')
        if r.get("versus"):
            v = r["versus"]
            said = {"below": "below", "above": "above", "near": "within a factor of"}.get(v.get("holds"), "")
            notes.append(f'ours in <code>{_e(r["run"])}</code> / ours in <code>{_e(v["run"])}</code> = '
                         f'{_fmt(r["ratio"])}' + (f' (holds if {said} {_fmt(v.get("factor", 1.0))})' if said else ""))
        out.append(
            f'<tr class="row-{_e(r["status"])}" id="t-{_e(r["id"])}" data-status="{_e(r["status"])}">'
            f'<td><code>{_e(r["id"])}</code></td><td>{_e(r["where"])}</td>'
            f'<td>{_e(r["quantity"])}{"<div class=reason>" + "<br>".join(notes) + "</div>" if notes else ""}</td>'
            f'<td class=num>{_fmt(r["thesis"])}</td><td class=num>{_fmt(r["ours"])}</td>'
            f'<td class=num>{_fmt(r["difference"])}</td><td>{_e(r["unit"])}</td>'
            f'<td>{_e(r["tolerance"])}<div class=reason>{_e(r["reason"])}</div></td>'
            f'<td class=status>{_STATUS_TEXT[r["status"]]}</td></tr>')
    return "".join(out)


def provenance(runs: list[dict]) -> str:
    """Which runs were flown for this report and which were taken from the run cache.

    Parameters
    ----------
    runs : list of dict
        ``report.json``'s runs, each with ``cached`` (True: taken from the cache, flown earlier by the same
        code version).

    Returns
    -------
    str
        One clause for the page and the terminal, e.g. "3 runs flown for this report, 24 taken from the run
        cache (flown earlier by this code version; --no-cache flies them again)".
    """
    cached = sum(1 for r in runs if r.get("cached"))
    fresh = len(runs) - cached
    why = "flown earlier by this code version; --no-cache flies them again"
    if not cached:
        return f"all {fresh} runs flown for this report"
    if not fresh:
        return f"all {cached} runs taken from the run cache ({why})"
    return f"{fresh} runs flown for this report, {cached} taken from the run cache ({why})"


def _vehicles_section(document: dict, runs: dict) -> str:
    """The two vehicles side by side: what the self-test found on each and how each law flew the same steps."""
    rows = document.get("vehicles")
    if not rows:
        return ""
    law_names = {"mfol": "fixed gains (self-tested)", "explicit": "explicit self-tuner", "gmv": "GMV self-tuner"}
    found = "".join(
        f"<tr><td><code>{_e(r['vehicle'])}</code></td><td>{_e(r['inputs'])}</td><td class=num>{r['self_test_s']:.1f}</td>"
        f"<td class=num>{' x '.join(f'{v:.1f}' for v in r['space_m'])}</td>"
        f"<td class=num>{', '.join(f'{v:.3g}' for v in r['b0inv_diagonal'])}</td>"
        f"<td class=num>{100 * r['off_diagonal_share']:.1f} %</td></tr>" for r in rows)
    flown = "".join(
        f"<tr><td><code>{_e(r['vehicle'])}</code></td><td>{_e(law_names.get(law, law))}</td>"
        + "".join(f"<td class=num>{100 * h['share']:.1f} % ({h['interaction']:.3f})</td>"
                  for h in (entry["held"][k] for k in ("u", "v", "w", "r")))
        + f"<td class=num>{100 * entry['input_peak_share']:.0f} %</td></tr>"
        for r in rows for law, entry in r["laws"].items())
    figures = "".join(_figure(f["path"], f["caption"]) for f in runs.get("vehicles", {}).get("figures", []))
    worst = max(h["share"] for r in rows for entry in r["laws"].values() for h in entry["held"].values())
    return (
        '<section id="vehicles"><h2>Two vehicles, one method</h2>'
        "<p>The thesis's claim (its abstract and ch. 8): hydrodynamic models are too expensive and uncertain, so an "
        "ROV's autopilot must be designed on the vehicle itself -- the self-test and the self-tuners need no "
        "a-priori model. Here the same procedure, with no model of either vehicle, on the Seapup and on a BlueROV2 "
        "Heavy of a quite different build (13.5 kg against 110 kg, eight fixed-pitch thrusters flown through four "
        "virtual inputs against four controllable-pitch ones; <code>docs/vehicles.md</code>). "
        "The BlueROV2 needed one operator's choice the thesis also leaves to the operator: faster poles for its "
        "undamped sway and yaw (the description's <code>self_test</code>).</p>"
        "<h3>What the self-test found at rest</h3><table><thead><tr><th>vehicle</th><th>inputs</th>"
        "<th>time [s]</th><th>box of water [m]</th><th>B0<sup>-1</sup> diagonal (u, v, w [m/s], r [rad/s] per unit "
        "input: a radian of blade pitch, or a virtual input's full scale)</th>"
        "<th>largest off-diagonal, of its row's diagonal</th></tr></thead>"
        f"<tbody>{found}</tbody></table><p>The Seapup's inputs are coupled by its build (both mains drive surge and "
        "yaw, the vectored pair sway and heave: eq. 5.3's matrices are far from diagonal), a virtual-input vehicle's "
        "are decoupled by its mixer.</p>"
        "<h3>How each law flew the same steps</h3><p>0.3 m/s surge, 0.15 m/s sway, 0.1 m/s heave and 0.2 rad/s "
        "yaw, 10 s each, the baseline instruments: the RMS error of the stepped output over the step's last 5 s as "
        "a share of its step (in brackets the other velocities' largest excursion there [m/s]), and the inputs' "
        "peak as a share of the vehicle's limit.</p><table><thead><tr><th>vehicle</th><th>law</th><th>u</th>"
        "<th>v</th><th>w</th><th>r</th><th>input peak</th></tr></thead>"
        f"<tbody>{flown}</tbody></table>"
        f"<p>Every law held every step within {100 * worst:.0f} % RMS of its size on both vehicles, none of them given "
        "a model of either: on this evidence the method carries to a vehicle it was not developed on, as the "
        "thesis claims, with the choice it leaves to the operator (the poles) and one more here (how long the "
        f"self-tuners fly the fixed gains before they adapt).</p>{figures}</section>")


def write_page(document: dict, path: Path) -> Path:
    """``report.html`` from ``report.json``'s document (figures read from the runs' directories)."""
    rows, runs = document["targets"], {r["name"]: r for r in document["runs"]}
    chapters = []
    for ch, counts in document["chapters"].items():
        mine = [r for r in rows if r["chapter"] == ch]
        run_names = list(dict.fromkeys(r["run"] for r in mine))
        figures = "".join(_figure(f["path"], f["caption"]) for name in run_names for f in runs[name]["figures"])
        errors = "".join(f"<p class=muted>run <code>{_e(n)}</code> failed: {_e(runs[n]['error'])}</p>"
                         for n in run_names if runs[n].get("error"))
        chapters.append(
            f'<section class="chapter" id="chapter-{_e(ch)}"><h2>{_e(CHAPTER_TITLES.get(ch, ch))}</h2>'
            f'<p>{counts["reproduced"]} of {counts["asked"]} reproduced, {counts["deviations"]} documented '
            f'deviations, {counts["failed"]} failed, {counts["not_run"]} not run. Runs: '
            + ", ".join(f'<code>{_e(n)}</code>' for n in run_names) + f".</p>{errors}"
            f"<table><thead><tr><th>id</th><th>where</th><th>quantity</th><th>thesis</th><th>ours</th>"
            f"<th>difference</th><th>unit</th><th>tolerance (why)</th><th>status</th></tr></thead>"
            f"<tbody>{_target_rows(mine)}</tbody></table>"
            + (f"<h3>Our analogues of the thesis's figures</h3>{figures}" if figures else "") + "</section>")
    deviations = {}
    for r in rows:
        if r["deviation"]:
            deviations.setdefault((r["deviation"]["doc"], r["deviation"]["decision"], r["deviation"]["reason"]),
                                  []).append(r)
    def link(target_id):
        return f'<a href="#t-{_e(target_id)}">{_e(target_id)}</a>'
    register = "".join(
        f"<tr><td class=cls title=\"{_e(CAUSE_CLASSES.get(group[0]['deviation'].get('class', ''), ''))}\">"
        f"{_e(group[0]['deviation'].get('class', ''))}</td><td>{', '.join(link(r['id']) for r in group)}</td>"
        f"<td>{_e(decision)}</td><td>{_e(reason)}</td>"
        f"<td>{_e(group[0]['deviation'].get('passage', ''))}</td><td><code>{_e(doc)}</code></td>"
        f"<td>{sum(r['status'] == 'deviation' for r in group)} of {len(group)} missed</td></tr>"
        for (doc, decision, reason), group in sorted(deviations.items(),
                                                     key=lambda item: item[1][0]['deviation'].get('class', '')))
    by_class = document["pooled"].get("by_class", {})
    classes = "".join(f"<li><b>({_e(c)})</b> {_e(text)}: {by_class.get(c, 0)} missed targets</li>"
                      for c, text in CAUSE_CLASSES.items())
    typos = "".join(f"<tr><td>{link(r['id'])}</td><td>{_e(r['where'])}</td>"
                    f"<td>{_e(r['typo']['read'])}</td><td>{_e(r['typo']['why'])}</td></tr>"
                    for r in rows if r["typo"] and (r["id"].endswith("[0,0]") or "[" not in r["id"]))
    largest = "".join(
        f"<li>{link(m['id'])} ({_e(m['where'])}, {_e(m['quantity'])}): {_STATUS_TEXT[m['status']]}, "
        + (f"{m['tolerances_away']:.1f} tolerances away" if m["tolerances_away"] is not None else "no value")
        + "</li>" for m in document["largest_misses"])
    made = document["made"]
    run_rows = "".join(
        f"<tr><td><code>{_e(r['name'])}</code></td><td>{_e(r['doc'])}</td><td>{'cache' if r['cached'] else 'run'}</td>"
        f"<td class=num>{_fmt(r['wall_s'])}</td><td class=num>{_fmt(r['cpu_s'])}</td>"
        f"<td>{_e(r['error'] or '')}</td></tr>" for r in document["runs"])
    page = f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><meta name="viewport" content="width=device-width, initial-scale=1">
<title>seapup: reproduction of Goheen's thesis ({_e(document['commit'])})</title><style>{_CSS}</style></head>
<body>
<h1>seapup: the thesis against ours</h1>
<p class=muted>K. R. Goheen, <i>The Modelling and Control of Remotely Operated Underwater Vehicles</i>: every
result the targets file asks for, scored against runs of commit <code>{_e(document['commit'])}</code> on
{_e(document['date'])}: {_e(provenance(document['runs']))}. A target is <b>reproduced</b> when ours lies within its tolerance (each with its reason),
a <b>deviation</b> when it is missed for a documented, decided reason (never counted as reproduced),
<b>failed</b> when missed otherwise.</p>
<section id="summary"><h2>Summary</h2>
<table><thead><tr><th>chapter</th><th>asked</th><th>reproduced</th><th>share</th><th>deviations</th><th>failed</th>
<th>not run</th><th></th></tr></thead><tbody>{_summary_rows(document)}</tbody></table>
<h3>The largest misses</h3><ol>{largest or '<li>none</li>'}</ol></section>
{''.join(chapters)}
{_vehicles_section(document, runs)}
<section id="deviations"><h2>Deviation register</h2>
<p>Each documented difference, the class of its cause, its decision and reason and the thesis's passage that
decides it; the full entry is in the named page of the docs. The missed targets by the class of their cause:</p>
<ul>{classes}</ul>
<table><thead><tr><th>class</th><th>targets</th><th>decision</th><th>reason</th><th>the thesis's passage</th>
<th>entry</th><th>now</th></tr></thead>
<tbody>{register or '<tr><td colspan=7>none</td></tr>'}</tbody></table>
<h3>Thesis typos we read around</h3>
<table><thead><tr><th>target</th><th>where</th><th>we read</th><th>why</th></tr></thead>
<tbody>{typos or '<tr><td colspan=4>none</td></tr>'}</tbody></table></section>
<section id="made"><h2>How this page was made</h2>
<p><code>./seapup report {_e(' '.join(made['argv']))}</code> at commit <code>{_e(document['commit'])}</code>
(code version <code>{_e(made['code_version'])}</code>), {_e(document['date'])}, on {_e(made['machine'])};
{made['wall_s']:.1f} s wall, {made['cpu_s']:.1f} s CPU in this process, {made['jobs']} parallel run(s).
Seeds: every run uses its random streams' seed 0 (verify's current statistics: seed 1). Targets:
<code>{_e(made['targets_file'])}</code>.</p>
<table><thead><tr><th>run</th><th>what</th><th>from</th><th>wall [s]</th><th>CPU [s]</th><th>error</th></tr></thead>
<tbody>{run_rows}</tbody></table></section>
</body></html>
"""
    path.write_text(page)
    return path


# -- the README's block --------------------------------------------------------------------------------------------
README_BEGIN = "<!-- generated by ./seapup report --readme README.md; do not edit by hand -->"
README_END = "<!-- end of the generated block -->"


def readme_block(document: dict) -> str:
    """The README's score table (markdown) from a report's document, between its two marker lines."""
    lines = [README_BEGIN, "", "| chapter | reproduced | documented deviations | failed |", "|---|---|---|---|"]
    for ch, c in list(document["chapters"].items()) + [("pooled", document["pooled"])]:
        name = CHAPTER_TITLES.get(ch, ch) if ch != "pooled" else "**pooled**"
        share = 100.0 * c["reproduced"] / c["asked"] if c["asked"] else 0.0
        lines.append(f"| {name} | {c['reproduced']} of {c['asked']} ({share:.0f} %) | {c['deviations']} | {c['failed']} |")
    missing = [CHAPTER_TITLES[ch] for ch in CHAPTER_TITLES if ch not in document["chapters"]]
    if missing:
        lines += ["", "Not yet in the targets file: " + "; ".join(missing) + "."]
    return "\n".join(lines + ["", README_END])


def update_readme(path: Path, document: dict) -> bool:
    """Replace the generated block of ``path``; True if it changed. ValueError without the markers."""
    from seapup_common.input_files import read_text
    text = read_text(path, "data")
    if README_BEGIN not in text or README_END not in text:
        raise ValueError(f"{path} has no generated block ({README_BEGIN!r} ... {README_END!r})")
    head, rest = text.split(README_BEGIN, 1)
    new = head + readme_block(document) + rest.split(README_END, 1)[1]
    path.write_text(new)
    return new != text
