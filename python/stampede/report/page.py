"""The report's HTML: one self-contained page (inline CSS, figures as PNG files beside it, no
scripts, nothing fetched), each figure with its numbers in a table beside it."""

import html
import math

STYLE = """
body { font-family: sans-serif; margin: 1.5em auto; max-width: 1350px; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; border-bottom: 1px solid #ccc; margin-top: 1.6em; }
.row { display: flex; flex-wrap: wrap; gap: 1.5em; align-items: flex-start; }
.row img { max-width: 64%; border: 1px solid #eee; }
.row > div { flex: 1 1 320px; min-width: 0; }
table { border-collapse: collapse; font-size: 0.85em; margin-bottom: 0.8em; }
th, td { border: 1px solid #ddd; padding: 2px 6px; text-align: right; white-space: nowrap; }
th { background: #f4f4f4; } td.text, th.text { text-align: left; }
pre { background: #f8f8f8; padding: 0.5em; font-size: 0.85em; overflow-x: auto; }
.note { color: #555; font-size: 0.85em; max-width: 60em; }
details { margin: 0.4em 0; }
"""


def number(v, digits=4):
    if isinstance(v, str):
        return v
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "–"
    if isinstance(v, (int,)) and not isinstance(v, bool):
        return str(v)
    return f"{v:.{digits}g}"


def table(rows, header=None, text_columns=(0,), digits=4):
    """An HTML table; cells are numbers (formatted to `digits` significant digits) or strings
    (escaped)."""
    out = ["<table>"]
    if header:
        out.append("<tr>" + "".join(f'<th class="{"text" if i in text_columns else ""}">{html.escape(str(h))}</th>'
                                    for i, h in enumerate(header)) + "</tr>")
    for row in rows:
        out.append("<tr>" + "".join(f'<td class="{"text" if i in text_columns else ""}">{html.escape(number(c, digits))}</td>'
                                    for i, c in enumerate(row)) + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def pre(lines):
    return "<pre>" + html.escape("\n".join(lines)) + "</pre>"


def note(text):
    return f'<p class="note">{html.escape(text)}</p>'


class Page:
    def __init__(self, title):
        self.title, self.parts = title, []

    def section(self, heading, figure=None, beside=(), below=()):
        """A heading, a figure (file name beside the page) with `beside` (HTML blocks) to its
        right, then `below`."""
        self.parts.append(f"<h2 id=\"{html.escape(heading.split(':')[0].lower().replace(' ', '-'))}\">"
                          f"{html.escape(heading)}</h2>")
        self.parts.append('<div class="row">')
        if figure:
            self.parts.append(f'<img src="{html.escape(figure)}" alt="{html.escape(heading)}">')
        self.parts.append("<div>" + "\n".join(beside) + "</div></div>")
        self.parts.extend(below)

    def html(self):
        return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
                f"<title>{html.escape(self.title)}</title><style>{STYLE}</style></head><body>\n"
                f"<h1>{html.escape(self.title)}</h1>\n" + "\n".join(self.parts) + "\n</body></html>\n")
