"""A tiny document model rendered twice: Markdown (figures linked) and HTML (embedded).

The report is built once as a list of blocks; both renderings come from the same list,
so the two files cannot disagree. Inline text understands only ```code```,
``**bold**`` and ``*emphasis*``.
"""

from __future__ import annotations

import base64
import html
import re
from dataclasses import dataclass, field
from pathlib import Path

_INLINE = re.compile(r"`([^`]+)`|\*\*([^*]+)\*\*|\*([^*\s](?:[^*]*[^*\s])?)\*")

_CSS = """
body { font-family: system-ui, sans-serif; max-width: 60rem; margin: 2rem auto;
       padding: 0 1rem; line-height: 1.45; color: #222; }
table { border-collapse: collapse; margin: 1rem 0; font-size: 0.92rem; }
th, td { border: 1px solid #bbb; padding: 0.3rem 0.6rem; text-align: left;
         vertical-align: top; }
th { background: #eee; }
code { background: #f3f3f3; padding: 0 0.2rem; }
figure { margin: 1.5rem 0; } figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: 0.9rem; color: #444; }
"""


def _html_inline(text: str) -> str:
    out, pos = [], 0
    for match in _INLINE.finditer(text):
        out.append(html.escape(text[pos : match.start()]))
        code, bold, emph = match.groups()
        if code:
            out.append(f"<code>{html.escape(code)}</code>")
        elif bold:
            out.append(f"<strong>{html.escape(bold)}</strong>")
        else:
            out.append(f"<em>{html.escape(emph)}</em>")
        pos = match.end()
    out.append(html.escape(text[pos:]))
    return "".join(out)


def _md_cell(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


@dataclass
class Document:
    """An ordered list of blocks: headings, paragraphs, bullet lists, tables, figures."""

    title: str
    blocks: list[tuple] = field(default_factory=list)

    def heading(self, text: str, level: int = 2) -> None:
        self.blocks.append(("heading", level, text))

    def paragraph(self, text: str) -> None:
        self.blocks.append(("paragraph", text))

    def bullets(self, items) -> None:
        self.blocks.append(("bullets", list(items)))

    def table(self, header, rows) -> None:
        self.blocks.append(("table", list(header), [list(map(str, r)) for r in rows]))

    def figure(self, path: Path, caption: str) -> None:
        self.blocks.append(("figure", Path(path), caption))

    # ------------------------------------------------------------------ renderers
    def to_markdown(self) -> str:
        """Markdown; figures are linked by file name (they sit next to the report)."""
        lines = [f"# {self.title}", ""]
        for block in self.blocks:
            kind = block[0]
            if kind == "heading":
                lines += ["#" * block[1] + " " + block[2], ""]
            elif kind == "paragraph":
                lines += [block[1], ""]
            elif kind == "bullets":
                lines += [f"- {item}" for item in block[1]] + [""]
            elif kind == "table":
                header, rows = block[1], block[2]
                lines.append("| " + " | ".join(_md_cell(h) for h in header) + " |")
                lines.append("|" + "---|" * len(header))
                lines += ["| " + " | ".join(_md_cell(c) for c in r) + " |" for r in rows]
                lines.append("")
            elif kind == "figure":
                lines += [f"![{block[2]}]({block[1].name})", "", f"*{block[2]}*", ""]
        return "\n".join(lines)

    def to_html(self) -> str:
        """A standalone HTML page; figures are embedded as base64 PNG."""
        parts = [
            "<!DOCTYPE html>",
            '<html lang="en"><head><meta charset="utf-8">',
            f"<title>{html.escape(self.title)}</title><style>{_CSS}</style></head><body>",
            f"<h1>{_html_inline(self.title)}</h1>",
        ]
        for block in self.blocks:
            kind = block[0]
            if kind == "heading":
                parts.append(f"<h{block[1]}>{_html_inline(block[2])}</h{block[1]}>")
            elif kind == "paragraph":
                parts.append(f"<p>{_html_inline(block[1])}</p>")
            elif kind == "bullets":
                items = "".join(f"<li>{_html_inline(i)}</li>" for i in block[1])
                parts.append(f"<ul>{items}</ul>")
            elif kind == "table":
                head = "".join(f"<th>{_html_inline(h)}</th>" for h in block[1])
                body = "".join(
                    "<tr>" + "".join(f"<td>{_html_inline(c)}</td>" for c in row) + "</tr>"
                    for row in block[2]
                )
                parts.append(f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>")
            elif kind == "figure":
                data = base64.b64encode(block[1].read_bytes()).decode("ascii")
                parts.append(
                    f'<figure><img alt="{html.escape(block[2])}" '
                    f'src="data:image/png;base64,{data}">'
                    f"<figcaption>{_html_inline(block[2])}</figcaption></figure>"
                )
        parts.append("</body></html>")
        return "\n".join(parts)
