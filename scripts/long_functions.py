#!/usr/bin/env python3
"""List Rust functions longer than a limit (default 80 lines), outside tests.

Usage: scripts/long_functions.py [DIR ...] [--limit N]   (default DIR: pipeline/src)
Prints `file:line name length`, longest first. A function's length counts the
lines from its `fn` line to its closing brace. Bodies are found by brace
matching after blanking out comments, strings and char literals; items inside
`#[cfg(test)]` modules and `tests.rs` files are skipped.
"""
import os
import re
import sys


def blank(src):
    """Replace comments, string and char literals by spaces (newlines kept)."""
    out, i, n = [], 0, len(src)
    while i < n:
        c = src[i]
        if src.startswith("//", i):
            j = src.find("\n", i)
            j = n if j < 0 else j
            out.append(" " * (j - i))
            i = j
        elif src.startswith("/*", i):
            depth, j = 1, i + 2
            while j < n and depth:
                if src.startswith("/*", j):
                    depth, j = depth + 1, j + 2
                elif src.startswith("*/", j):
                    depth, j = depth - 1, j + 2
                else:
                    j += 1
            out.append(re.sub(r"[^\n]", " ", src[i:j]))
            i = j
        elif c == "r" and re.match(r'r#*"', src[i:i + 10]) and (i == 0 or not (src[i - 1].isalnum() or src[i - 1] == "_")):
            m = re.match(r'r(#*)"', src[i:])
            end = src.find('"' + m.group(1), i + len(m.group(0)))
            j = n if end < 0 else end + 1 + len(m.group(1))
            out.append(re.sub(r"[^\n]", " ", src[i:j]))
            i = j
        elif c == '"':
            j = i + 1
            while j < n and src[j] != '"':
                j += 2 if src[j] == "\\" else 1
            out.append(re.sub(r"[^\n]", " ", src[i:j + 1]))
            i = j + 1
        elif c == "'":
            # a char literal ('a', '\n', '\u{..}') but not a lifetime ('a)
            m = re.match(r"'(\\u\{[0-9a-fA-F]+\}|\\.|[^\\'])'", src[i:])
            if m:
                out.append(" " * len(m.group(0)))
                i += len(m.group(0))
            else:
                out.append(c)
                i += 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


def match_brace(text, open_at):
    depth = 0
    for j in range(open_at, len(text)):
        if text[j] == "{":
            depth += 1
        elif text[j] == "}":
            depth -= 1
            if depth == 0:
                return j
    return len(text) - 1


FN = re.compile(r"\bfn\s+([A-Za-z_][A-Za-z0-9_]*)")
TEST_MOD = re.compile(r"#\[cfg\(test\)\]\s*(pub(\([^)]*\))?\s+)?mod\s+\w+\s*\{")


def functions(path):
    text = blank(open(path, encoding="utf-8").read())
    skip = []  # byte ranges of test modules
    for m in TEST_MOD.finditer(text):
        skip.append((m.start(), match_brace(text, m.end() - 1)))
    for m in FN.finditer(text):
        if any(a <= m.start() <= b for a, b in skip):
            continue
        # the body opens at the first `{` after the signature; a `;` first means no body
        j = m.end()
        while j < len(text) and text[j] not in "{;":
            j += 1
        if j >= len(text) or text[j] == ";":
            continue
        end = match_brace(text, j)
        first = text.count("\n", 0, m.start()) + 1
        last = text.count("\n", 0, end) + 1
        yield first, m.group(1), last - first + 1


def main(argv):
    limit, dirs = 80, []
    it = iter(argv)
    for a in it:
        if a == "--limit":
            limit = int(next(it))
        else:
            dirs.append(a)
    rows = []
    for d in dirs or ["pipeline/src"]:
        for root, _, files in os.walk(d):
            for f in files:
                if not f.endswith(".rs") or f == "tests.rs":
                    continue
                path = os.path.join(root, f)
                for line, name, length in functions(path):
                    if length > limit:
                        rows.append((length, path, line, name))
    for length, path, line, name in sorted(rows, key=lambda r: (-r[0], r[1], r[2])):
        print(f"{path}:{line} {name} {length}")


if __name__ == "__main__":
    main(sys.argv[1:])
