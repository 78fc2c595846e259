#!/usr/bin/env python3
"""List the workspace's long Rust functions, longest first.

scripts/long-functions.py [N]        (N: the least length shown, 150 unless given)

Reads every crates/*/src/**/*.rs (not tests/, benches/ or target/; a `#[cfg(test)]` item
and a test module's own file, `tests.rs` or `*_tests.rs`, are left out too) and prints
each function of at least N lines as `length  file:line  name`, then how many there are.
The length counts the lines from the one holding `fn` to the one holding the closing
brace, both included. Braces inside strings (raw and byte strings too), character
literals and comments (nested block comments too) are not counted; lifetimes are told
from character literals. A declaration without a body (`fn f();`) is not a function here.
"""
import bisect
import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def code_tokens(text):
    """Yields (offset, token) for each brace, bracket, parenthesis, `;`, `#[cfg(test)]` and
    word outside literals and comments."""
    i, n = 0, len(text)
    word = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
    raw_string = re.compile(r"b?r(#*)\"")
    char_literal = re.compile(r"'(\\u\{[0-9A-Fa-f]*\}|\\.[^']*|[^\\'])'")
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            i = text.find("\n", i)
            i = n if i < 0 else i
        elif text.startswith("/*", i):
            depth, i = 1, i + 2
            while i < n and depth:
                if text.startswith("/*", i):
                    depth, i = depth + 1, i + 2
                elif text.startswith("*/", i):
                    depth, i = depth - 1, i + 2
                else:
                    i += 1
        elif raw := raw_string.match(text, i):
            end = '"' + raw.group(1)
            j = text.find(end, i + raw.end())
            i = n if j < 0 else j + len(end)
        elif c == '"' or text.startswith('b"', i):
            i = text.index('"', i) + 1
            while i < n and text[i] != '"':
                i += 2 if text[i] == "\\" else 1
            i += 1
        elif c == "'" or text.startswith("b'", i):
            start = text.index("'", i)
            # A character literal: 'x', '\n', '\u{..}', '\''; otherwise a lifetime or label.
            lit = char_literal.match(text, start, start + 16)
            i = lit.end() if lit else start + 1
        elif text.startswith("#[cfg(test)]", i):
            yield i, "#[cfg(test)]"
            i += len("#[cfg(test)]")
        elif c in "{}[]();":
            yield i, c
            i += 1
        elif m := word.match(text, i):
            yield i, m.group(0)
            i = m.end()
        else:
            i += 1


def functions(text):
    """Yields (first line, last line, name) of each function with a body outside test items."""
    tokens = list(code_tokens(text))
    line_starts = [0] + [m.end() for m in re.finditer("\n", text)]
    line_of = lambda offset: bisect.bisect_right(line_starts, offset)  # noqa: E731
    close = {}  # index of each `{` token -> index of its `}`
    stack = []
    for k, (_, tok) in enumerate(tokens):
        if tok == "{":
            stack.append(k)
        elif tok == "}" and stack:
            close[stack.pop()] = k
    skip_until = -1
    for k, (offset, tok) in enumerate(tokens):
        if k <= skip_until:
            continue
        if tok == "#[cfg(test)]":
            # The item it marks ends at its body's closing brace or at a `;` before any body.
            j = k + 1
            while j < len(tokens) and tokens[j][1] not in ("{", ";"):
                j += 1
            if j < len(tokens) and tokens[j][1] == "{":
                skip_until = close.get(j, len(tokens))
            continue
        if tok != "fn" or k + 1 >= len(tokens):
            continue
        name = tokens[k + 1][1]
        if not re.match(r"[A-Za-z_]", name):
            continue
        # The body is the first `{` after the signature; a `;` first (outside the
        # parameters' and types' brackets, as in `[u8; 4]`) ends a declaration.
        j, depth = k + 1, 0
        while j < len(tokens) and not (depth == 0 and tokens[j][1] in ("{", ";")):
            depth += {"(": 1, "[": 1, ")": -1, "]": -1}.get(tokens[j][1], 0)
            j += 1
        if j >= len(tokens) or tokens[j][1] == ";" or j not in close:
            continue
        yield line_of(offset), line_of(tokens[close[j]][0]), name


def main():
    least = int(sys.argv[1]) if len(sys.argv) > 1 else 150
    found = []
    crates = os.path.join(ROOT, "crates")
    for crate in sorted(os.listdir(crates)):
        src = os.path.join(crates, crate, "src")
        for folder, dirs, files in os.walk(src):
            dirs[:] = sorted(d for d in dirs if d not in ("tests", "target"))
            for name in sorted(files):
                if not name.endswith(".rs") or name == "tests.rs" or name.endswith("_tests.rs"):
                    continue
                path = os.path.join(folder, name)
                with open(path, encoding="utf-8") as f:
                    text = f.read()
                for first, last, fn in functions(text):
                    if last - first + 1 >= least:
                        found.append((last - first + 1, os.path.relpath(path, ROOT), first, fn))
    found.sort(key=lambda f: (-f[0], f[1], f[2]))
    for length, path, line, fn in found:
        print(f"{length:5}  {path}:{line}  {fn}")
    print(f"{len(found)} functions of {least} lines or more")


if __name__ == "__main__":
    main()
