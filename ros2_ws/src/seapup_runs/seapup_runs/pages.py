"""What the product's HTML pages share (the reproduction report, the demo's index): a style sheet,
escaping, number formatting and figures embedded as PNG data, so a page is one self-contained file."""
from __future__ import annotations

import base64
import html
from pathlib import Path

__all__ = ["CSS", "esc", "fmt", "figure"]

CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",sans-serif;margin:0 auto;max-width:1200px;padding:1em 2em;
color:#1d2329;line-height:1.4}
h1{font-size:1.6em;margin-bottom:.2em}h2{border-bottom:2px solid #d0d7de;padding-bottom:.2em;margin-top:2em}
table{border-collapse:collapse;margin:.6em 0;font-size:.86em;width:100%}
th,td{border:1px solid #d0d7de;padding:.25em .45em;text-align:left;vertical-align:top}
th{background:#f3f5f7}td.num{text-align:right;font-variant-numeric:tabular-nums;white-space:nowrap}
tr.row-reproduced td.status,tr.row-passed td.status{background:#cdebd0;color:#14532d}
tr.row-deviation td.status{background:#fbe7b5;color:#713f12}
tr.row-failed td.status{background:#f8c9c9;color:#7f1d1d;font-weight:600}
tr.row-not_run td.status{background:#e5e7eb;color:#374151}
.reason{color:#57606a;font-size:.9em}.muted{color:#57606a}
figure{display:inline-block;margin:.6em .8em .6em 0;max-width:48%;vertical-align:top}
figure.wide{max-width:100%}
figure img{max-width:100%;border:1px solid #d0d7de}figcaption{font-size:.85em;color:#57606a}
.bar{display:inline-block;height:.8em;background:#2da44e;vertical-align:middle}
.bar.dev{background:#d4a72c}.bar.fail{background:#cf222e}.bar.nr{background:#afb8c1}
code{font-size:.92em}pre{background:#f6f8fa;padding:.6em;overflow-x:auto;font-size:.85em}
"""


def esc(text) -> str:
    """``text`` escaped for HTML text and attribute values."""
    return html.escape(str(text), quote=True)


def fmt(value) -> str:
    """A number for a table cell: 4 significant figures, yes/no for a boolean, a dash for none."""
    if value is None:
        return "\u2014"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return str(value)
    value = float(value)
    if value != value:
        return "\u2014"
    if value == 0:
        return "0"
    if abs(value) >= 1e4 or abs(value) < 1e-3:
        return f"{value:.3e}"
    return f"{value:.4g}"


def figure(path, caption: str, wide: bool = False) -> str:
    """A PNG file as an embedded ``<figure>`` (a short note instead if the file is missing)."""
    try:
        data = base64.b64encode(Path(path).read_bytes()).decode()
    except OSError:
        return f"<p class=muted>figure {esc(Path(path).name)} missing</p>"
    return (f'<figure{" class=wide" if wide else ""}><img alt="{esc(caption)}" src="data:image/png;base64,{data}">'
            f"<figcaption>{esc(caption)}</figcaption></figure>")
