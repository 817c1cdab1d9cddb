"""The docs' Markdown read with markdown-it-py (CommonMark, GitHub's tables); lines from 1."""
import re
from collections import namedtuple

from markdown_it import MarkdownIt
from markdown_it.tree import SyntaxTreeNode

parse = MarkdownIt("commonmark").enable("table").parse
Block = namedtuple("Block", "lang line body")     # a fenced code block: line of its body
Table = namedtuple("Table", "line header rows")   # cell texts; line of the header row


def tokens(text: str):
    """(line, token) of every token, an inline one followed by its text, code spans, links."""
    for t in parse(text):
        n = t.map[0] + 1 if t.map else 0
        yield n, t
        for child in t.children or []:
            yield n, child
            n += child.type in ("softbreak", "hardbreak")


def blocks(text: str) -> list[Block]:
    return [Block((t.info.split() or [""])[0].lower(), t.map[0] + 2, t.content[:-1])
            for t in parse(text) if t.type == "fence"]


def prose_lines(text: str) -> list[tuple[int, str]]:
    """(line number, line) of every line outside code blocks."""
    code = {n for t in parse(text) if t.type in ("fence", "code_block") for n in range(*t.map)}
    return [(n + 1, line) for n, line in enumerate(text.split("\n")) if n not in code]


def code_spans(text: str) -> list[str]:
    return [t.content.strip() for _, t in tokens(text) if t.type == "code_inline"]


def headings(text: str) -> list[tuple[int, int, str]]:
    """(line number, level, text) of every heading."""
    found = parse(text)
    return [(t.map[0] + 1, int(t.tag[1:]), "".join(c.content for c in found[i + 1].children
                                                   if c.type in ("text", "code_inline")))
            for i, t in enumerate(found) if t.type == "heading_open"]


def anchors(text: str) -> set[str]:
    """Every heading's GitHub anchor: its text in lower case, punctuation but - and _
    dropped, spaces to -; a repeated one gets -1, -2, ..."""
    slugs = [re.sub(r"[^\w\- ]", "", title.strip().lower()).replace(" ", "-")
             for _, _, title in headings(text)]
    return {f"{s}-{slugs[:i].count(s)}" if s in slugs[:i] else s for i, s in enumerate(slugs)}


def tables(text: str) -> list[Table]:
    found = [(node.map[0] + 1, [[cell.children[0].content for cell in row.children]
                                for part in node.children for row in part.children])
             for node in SyntaxTreeNode(parse(text)).walk() if node.type == "table"]
    return [Table(line, rows[0], rows[1:]) for line, rows in found]
