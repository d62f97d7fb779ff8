r"""Assemble the report: ONE self-contained HTML file (no network, no CDN, nothing external).

The style and the script are inlined from ``assets/``. The script is one closure written in parts
(``assets/js/*.js``, one per concern: models, data, selections, controls, each view), joined in
the order of :data:`SCRIPT_PARTS` when the page is written: no bundler. The data goes in a
``<script type="application/json">`` element with ``<``, ``>`` and ``&`` written as JSON
``\u003c``-style escapes, so no name in the data (a method called ``</script><img …>``) can ever end
the element or become markup. The script renders names with ``textContent`` only. A
Content-Security-Policy forbids every fetch: the page works offline and cannot leak data.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from importlib import resources
from pathlib import Path
from typing import Any

from dispeval_ros.errors import InputError

CSP = (
    "default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; "
    "img-src data:; connect-src 'none'; form-action 'none'; base-uri 'none'"
)


SCRIPT_PARTS = (
    "open",  # the closure opens; constants
    "numeric",
    "models",
    "data",
    "selections",
    "dom",
    "controls",
    "layout",
    "render",
    "curves",
    "bars",
    "latency",
    "temporal",
    "sweep",
    "parallel",
    "thumbnails",
    "start",  # main(); the closure closes
)
"""The parts of the page's script, in the one order they are joined (``assets/js/<part>.js``)."""


def _asset(name: str) -> str:
    try:
        return (
            resources.files("dispeval_ros.report")
            .joinpath("assets", *name.split("/"))
            .read_text("utf-8")
        )
    except (FileNotFoundError, OSError) as error:
        raise InputError(
            f"the report asset {name} is missing from this installation ({error}); "
            "dispeval_ros/report/assets/* must be installed as package data"
        ) from None


def report_script() -> str:
    """The page's script: the parts of :data:`SCRIPT_PARTS` joined in order."""
    return "".join(_asset(f"js/{part}.js") for part in SCRIPT_PARTS)


def script_json(data: Any) -> str:
    """JSON for a ``<script type="application/json">`` element: ``<``, ``>``, ``&`` escaped.

    Line and paragraph separators are escaped too (harmless in JSON, but not in every parser).
    """
    text = json.dumps(data, ensure_ascii=False, allow_nan=False, separators=(",", ":"))
    for char, escape in (
        ("&", "\\u0026"),
        ("<", "\\u003c"),
        (">", "\\u003e"),
        ("\u2028", "\\u2028"),
        ("\u2029", "\\u2029"),
    ):
        text = text.replace(char, escape)
    return text


def _text(value: str) -> str:
    """Escape text for the few places Python writes it into markup (the title)."""
    return (
        value.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;").replace('"', "&quot;")
    )


def render_html(data: Mapping[str, Any]) -> str:
    """The complete HTML document of report ``data`` (from ``build_report_data``)."""
    style = _asset("report.css")
    script = report_script()
    for name, text in (("report.css", style), ("report.js", script)):
        if "</" in text.replace("<\\/", ""):
            raise InputError(f"asset {name} contains '</', which would end its inline element")
    title = _text(str(data.get("title", "dispeval report")))
    return (
        "<!DOCTYPE html>\n"
        '<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        f'<meta http-equiv="Content-Security-Policy" content="{CSP}">\n'
        '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
        '<link rel="icon" href="data:,">\n'
        f"<title>{title}</title>\n"
        f"<style>\n{style}\n</style>\n</head>\n<body>\n"
        '<div id="app"><p id="loading">Loading the report…</p>'
        "<noscript><p>This report needs JavaScript (it computes the models in the "
        "browser).</p></noscript></div>\n"
        f'<script type="application/json" id="dispeval-data">{script_json(data)}</script>\n'
        f"<script>\n{script}\n</script>\n</body>\n</html>\n"
    )


def write_report(data: Mapping[str, Any], path: Path) -> int:
    """Write the report to ``path`` atomically; returns its size in bytes."""
    path = Path(path)
    text = render_html(data)
    partial = path.with_name(path.name + ".partial")
    try:
        if path.parent and not path.parent.exists():
            path.parent.mkdir(parents=True, exist_ok=True)
        partial.write_text(text, encoding="utf-8")
        os.replace(partial, path)
    except OSError as error:
        partial.unlink(missing_ok=True)
        raise InputError(f"{path}: cannot write the report ({error.strerror or error})") from None
    return path.stat().st_size
