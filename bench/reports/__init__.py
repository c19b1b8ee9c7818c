"""HTML pages of the bench's reports: one Jinja2 base page (``templates/base.html.j2``),
one stylesheet (``style.css``, inlined so a page is one self-contained file), macros for
tables, figures and level badges (``templates/macros.html.j2``), and the one helper that
embeds a matplotlib figure as a base64 PNG.

A page template extends the base::

    {% extends "base.html.j2" %}
    {% block content %}...{% endblock %}

and is rendered with `render(name, title=..., nav=[(href, label), ...], ...)`. A
`Document` (paragraphs, tables, figures, headings) renders both as markdown (`markdown`)
and, through the ``blocks`` macro, as HTML, so a report written once reads the same in
both.
"""

from __future__ import annotations

import base64
import io
import re
from dataclasses import dataclass, field
from functools import lru_cache
from importlib import resources
from typing import Any

import jinja2
from markupsafe import Markup, escape

from bench.core.verdict import Level

LEVEL_CLASSES = tuple(lv.name for lv in sorted(Level, key=lambda lv: (lv < 0, lv)))
"""Verdict levels the stylesheet colours (class ``v LEVEL``): `bench.core.verdict.Level`'s
names, HEALTHY to FAILURE then UNKNOWN."""


@dataclass
class Table:
    """A table: header cells, rows of cells (text), and which columns hold numbers
    (right-aligned; default: every column but the first)."""
    header: list[str]
    rows: list[list[str]]
    numeric: list[bool] | None = None
    role: str = ""
    """``summary``: the page's summary table (one row per item, the values of its JSON)."""
    caption: str = ""
    kind: str = "table"

    def is_numeric(self, k: int) -> bool:
        return self.numeric[k] if self.numeric is not None else k > 0

    def markdown(self) -> str:
        def cell(c: str) -> str:
            return str(c).replace("\n", " ").replace("|", "\\|")
        out = ["| " + " | ".join(cell(c) for c in self.header) + " |",
               "|" + "---|" * len(self.header)]
        out += ["| " + " | ".join(cell(c) for c in r) + " |" for r in self.rows]
        return "\n".join(out)


@dataclass
class Figure:
    """A figure: `src` a file path relative to the page, or `data` a base64 PNG; `alt`
    its text for a reader that shows no images (default: the caption)."""
    caption: str
    src: str = ""
    data: str = ""
    alt: str = ""
    kind: str = "figure"

    def markdown(self) -> str:
        return f"![{self.caption}]({self.src})" if self.src else ""


@dataclass
class Paragraph:
    """A paragraph of plain text; `code` spans are written between backticks. `role`
    is its class on the page (``note``: small print, ``ref``: what a verdict was judged
    against)."""
    text: str
    role: str = ""
    kind: str = "paragraph"

    def markdown(self) -> str:
        return str(self.text)


@dataclass
class Bullets:
    """A list of items (plain text, `code` spans between backticks, or `Markup`)."""
    items: list[Any]
    kind: str = "list"

    def markdown(self) -> str:
        return "\n".join(f"- {i}" for i in self.items)


@dataclass
class Preformatted:
    """Text shown as printed (a command's text output)."""
    text: str
    kind: str = "pre"

    def markdown(self) -> str:
        return "```\n" + self.text.rstrip("\n") + "\n```"


@dataclass
class Heading:
    text: str
    level: int = 2
    kind: str = "heading"

    @property
    def anchor(self) -> str:
        return anchor(self.text)

    def markdown(self) -> str:
        return "#" * self.level + " " + self.text


Block = Table | Figure | Paragraph | Bullets | Preformatted | Heading


@dataclass
class Document:
    """Blocks in order; `markdown()` and the ``blocks`` macro render them."""
    blocks: list[Block] = field(default_factory=list)

    def add(self, *blocks: Block | str) -> Document:
        for b in blocks:
            self.blocks.append(Paragraph(b) if isinstance(b, str) else b)
        return self

    def markdown(self) -> str:
        return "\n\n".join(b.markdown() for b in self.blocks if b.markdown()) + "\n"

    def headings(self, level: int = 2) -> list[Heading]:
        return [b for b in self.blocks if isinstance(b, Heading) and b.level == level]


def anchor(text: str) -> str:
    """An id for `text` (lower case, runs of other characters as one dash)."""
    return re.sub(r"[^a-z0-9]+", "-", str(text).lower()).strip("-") or "section"


def inline_code(text: Any) -> Markup:
    """`text` escaped, with spans between backticks as <code> (`Markup` as it is)."""
    if isinstance(text, Markup):
        return text
    parts = str(text).split("`")
    if len(parts) % 2 == 0:          # an odd backtick: keep it as written
        return escape(text)
    return Markup("").join(escape(p) if k % 2 == 0 else
                           Markup("<code>") + escape(p) + Markup("</code>")
                           for k, p in enumerate(parts))


def badge(level: str) -> Markup:
    """A verdict level as its coloured badge (an unknown word: the UNKNOWN colour)."""
    cls = level if level in LEVEL_CLASSES else Level.UNKNOWN.name
    return Markup('<span class="v {}">{}</span>').format(cls, level)


def link(href: str, text: str) -> Markup:
    """A link to `href` (a relative path or an anchor, quoted by the caller)."""
    return Markup('<a href="{}">{}</a>').format(href, text)


def strong(text: str) -> Markup:
    """`text` in bold (the chosen row of a ranking)."""
    return Markup("<b>{}</b>").format(text)


def marked(text: str) -> Markup:
    """`text` highlighted (a value outside its band)."""
    return Markup("<mark>{}</mark>").format(text)


def stylesheet() -> str:
    """The one stylesheet of every page."""
    return resources.files("bench.reports").joinpath("style.css").read_text(encoding="utf-8")


@lru_cache(maxsize=1)
def environment() -> jinja2.Environment:
    """The Jinja2 environment of the report templates (package data, autoescaped)."""
    env = jinja2.Environment(loader=jinja2.PackageLoader("bench.reports", "templates"),
                             autoescape=True, undefined=jinja2.StrictUndefined,
                             trim_blocks=True, lstrip_blocks=True)
    env.filters["code"] = inline_code
    env.filters["anchor"] = anchor
    env.globals["stylesheet"] = Markup(stylesheet())
    env.globals["level_classes"] = LEVEL_CLASSES
    return env


def render(template: str, **context: Any) -> str:
    """The HTML text of page template `template` (which extends ``base.html.j2``)."""
    context.setdefault("nav", [])
    context.setdefault("subtitle", "")
    return environment().get_template(template).render(**context)


def render_document(doc: Document, title: str, summary: Document | None = None,
                    footer: Document | None = None, **context: Any) -> str:
    """The HTML text of `doc` on the base page (``document.html.j2``), `summary` above
    it and `footer` below; `context`: subtitle, nav."""
    return render("document.html.j2", title=title, doc=doc,
                  summary=summary or Document(), footer=footer or Document(), **context)


def png_base64(fig: Any, dpi: int = 80, tight: bool = True) -> str:
    """A matplotlib figure as a base64 PNG, for ``<img src="data:image/png;base64,...">``
    (the page then needs no file beside it). Draw with matplotlib's `Figure` API: a
    pyplot figure stays open until pyplot closes it."""
    buf = io.BytesIO()
    if tight:
        fig.tight_layout()
    fig.savefig(buf, format="png", dpi=dpi)
    return base64.b64encode(buf.getvalue()).decode("ascii")
