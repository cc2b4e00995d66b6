#!/usr/bin/env python3
"""The README and the docs as a user finds them (run by CTest as docs_links).

Fails, naming file and line, when
- a relative link in README.md or any docs/**/*.md points to a file that does not exist, or to a
  heading (#anchor) that the target page does not have (GitHub's heading ids);
- a page under docs/ is not linked from the README's index (its "Documentation" section: the
  way in to every page);
- README.md is longer than 250 lines (the README is a front door; the rest belongs in docs/).

Usage: check_doc_links.py [REPOSITORY_ROOT]   (default: two levels above this file)
"""
import os
import re
import sys

README_MAX_LINES = 250

LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
CODE_SPAN = re.compile(r"(`+)(.+?)\1")
FENCE = re.compile(r"^\s*(```|~~~)")
HEADING = re.compile(r"^\s{0,3}(#{1,6})\s+(.*?)\s*#*\s*$")


def prose_lines(path):
    """(line number, text) of the lines outside fenced and indented code blocks, code spans
    blanked (a link inside code is an example, not a link)."""
    with open(path, encoding="utf-8") as f:
        lines = f.read().split("\n")
    in_fence = False
    previous_blank = True
    for number, line in enumerate(lines, 1):
        if FENCE.match(line):
            in_fence = not in_fence
            previous_blank = False
            continue
        if in_fence:
            continue
        # An indented code block starts after a blank line (inside a list it is a continuation,
        # which the docs indent by 2 or 3; 4 and more after a blank line is code).
        if line.startswith("    ") and previous_blank:
            continue
        previous_blank = line.strip() == ""
        yield number, CODE_SPAN.sub(lambda m: "x" * len(m.group(0)), line)


def slug(heading):
    """GitHub's id for a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"`", "", heading)
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", text)  # a link in a heading keeps its text
    text = text.strip().lower()
    text = "".join(c for c in text if c.isalnum() or c in " -_")
    return text.replace(" ", "-")


def anchors(path, cache={}):
    if path not in cache:
        found = set()
        seen = {}
        in_fence = False
        with open(path, encoding="utf-8") as f:
            for line in f:
                if FENCE.match(line):
                    in_fence = not in_fence
                    continue
                m = None if in_fence else HEADING.match(line)
                if m:
                    base = slug(m.group(2))
                    n = seen.get(base, 0)
                    seen[base] = n + 1
                    found.add(base if n == 0 else "%s-%d" % (base, n))
        cache[path] = found
    return cache[path]


def main():
    root = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else
                           os.path.join(os.path.dirname(__file__), "..", ".."))
    readme = os.path.join(root, "README.md")
    docs = os.path.join(root, "docs")
    pages = [readme]
    for directory, _, files in os.walk(docs):
        pages += [os.path.join(directory, f) for f in sorted(files) if f.endswith(".md")]

    problems = []
    indexed = set()
    in_index = False
    for page in pages:
        shown = os.path.relpath(page, root)
        for number, line in prose_lines(page):
            heading = HEADING.match(line)
            if page == readme and heading:
                in_index = heading.group(2).strip().lower() == "documentation"
            for m in LINK.finditer(line):
                target = m.group(1)
                if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.I):
                    continue  # http:, https:, mailto:
                path_part, _, anchor = target.partition("#")
                resolved = os.path.normpath(os.path.join(os.path.dirname(page), path_part)) \
                    if path_part else page
                if not os.path.exists(resolved):
                    problems.append("%s:%d: link to %s: no such file" % (shown, number, target))
                    continue
                if page == readme and in_index:
                    indexed.add(resolved)
                if anchor and resolved.endswith(".md") and anchor not in anchors(resolved):
                    problems.append("%s:%d: link to %s: %s has no heading with id '%s'" %
                                    (shown, number, target, os.path.relpath(resolved, root), anchor))

    for page in pages[1:]:
        if os.path.normpath(page) not in indexed:
            problems.append("README.md: %s is not in the README's index (section \"Documentation\")"
                            % os.path.relpath(page, root))

    with open(readme, encoding="utf-8") as f:
        readme_lines = f.read().rstrip("\n").count("\n") + 1
    if readme_lines > README_MAX_LINES:
        problems.append("README.md: %d lines, more than %d: move detail into docs/ and link it" %
                        (readme_lines, README_MAX_LINES))

    for p in problems:
        print(p)
    print("check_doc_links: %d page(s) checked, %d problem(s)" % (len(pages), len(problems)))
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
