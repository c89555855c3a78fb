#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""List the C++ functions longer than N lines in the given folders (issue 40: "no function over
~120 lines in processor/ outside tables"; docs/development.md lists the exceptions).

    tools/long-functions.py [--max N] [--ext .cpp,.hpp] FOLDER_OR_FILE...

Prints `path:line: LINES lines: Name`, longest first, and exits 0 (1 on a bad argument). LINES
counts from the line of the function's name to its closing brace, both included.

How it works, and its limits: it matches braces on clang-format'ed code (tools/check-format.sh),
after blanking comments, string and character literals (raw strings included). A `{` opens a
function body when the scopes around it are only namespaces, classes, structs, unions and
`extern "C"`, and the text since the previous `;`, `{` or `}` holds a parameter list with no `=`
outside parentheses (so tables and lambdas at namespace scope are not functions; `operator=`
is). Lambdas and local classes count toward the function that holds them. It does not run the
preprocessor: a function whose braces differ between `#if` branches, or a macro that opens or
closes a brace, confuses it. A constructor's initialiser list with `member{...}` braces is
skipped by a heuristic (an identifier or `>` right before the `{`, after a `:` that follows the
parameter list). Names are the token before the parameter list (`Class::Name`, `operator+`),
not the full signature, so overloads print once each with their own line numbers.
"""

import argparse
import os
import re
import sys

SCOPE_KEYWORDS = ("namespace", "class", "struct", "union", "enum")


def blank_literals(text):
    """The text with comments, string and character literals replaced by spaces (newlines kept,
    so that line numbers stay)."""
    out = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            out.append(" " * (j - i))
            i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif c == "R" and text.startswith('R"', i) and (i == 0 or not text[i - 1].isalnum()):
            m = re.match(r'R"([^(\s]*)\(', text[i:])
            if not m:
                out.append(c)
                i += 1
                continue
            end = text.find(")" + m.group(1) + '"', i)
            j = n if end < 0 else end + len(m.group(1)) + 2
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif c in "\"'":
            # A digit separator (1'000'000) is not a character literal.
            if c == "'" and i > 0 and text[i - 1].isalnum() and i + 1 < n and text[i + 1].isalnum():
                out.append(c)
                i += 1
                continue
            j = i + 1
            while j < n and text[j] != c and text[j] != "\n":
                j += 2 if text[j] == "\\" else 1
            j = min(j + 1, n)
            out.append(c + " " * (j - i - 2) + c if j - i >= 2 else " " * (j - i))
            i = j
        else:
            out.append(c)
            i += 1
    return "".join(out)


def strip_preprocessor(text):
    """Preprocessor lines (with their continuations) blanked."""
    lines = text.split("\n")
    cont = False
    for k, line in enumerate(lines):
        if cont or line.lstrip().startswith("#"):
            cont = line.rstrip().endswith("\\")
            lines[k] = ""
    return "\n".join(lines)


def top_level(segment, opener="(", closer=")"):
    """The segment with every bracketed part (opener..closer) removed."""
    depth, out = 0, []
    for c in segment:
        if c == opener:
            depth += 1
        elif c == closer:
            depth = max(0, depth - 1)
        elif depth == 0:
            out.append(c)
    return "".join(out)


def classify(segment):
    """What a `{` opens, from the text since the previous `;`, `{` or `}`: ('scope', None),
    ('function', name), ('init', None) (a member's braces in a constructor's initialiser list)
    or ('other', None)."""
    seg = " ".join(segment.split())
    head = re.sub(r"^template\s*<.*?>\s*", "", seg)
    if re.match(r'^extern\s+"\s*"$', seg) or re.match(r'^extern\s+"C"$', seg):
        return "scope", None
    words = re.findall(r"[A-Za-z_]\w*", top_level(head.split("(")[0] if "(" in head else head))
    if words and words[0] in ("typedef", "using"):
        return "other", None
    if any(w in SCOPE_KEYWORDS for w in words[:3]) and "(" not in head.split(":")[0]:
        return "scope", None
    if "(" not in head or ")" not in head:
        return "other", None
    flat = top_level(head)
    if "=" in flat.replace("==", "") and "operator" not in head:
        return "other", None
    # A constructor's initialiser list: `member{...}` after the `:` that follows the parameters.
    close = head.rfind(")")
    after = head[close + 1 :]
    if re.search(r"(^|\))\s*:", head[close:]) or re.search(r"\)\s*:\s*\w", head):
        if after.strip() and (after.rstrip()[-1:].isalnum() or after.rstrip().endswith(("_", ">"))):
            if not re.search(r"\b(const|override|final|noexcept|mutable)\s*$", after):
                return "init", None
    # The name: the token before the first top-level parameter list.
    depth, start = 0, None
    for k, c in enumerate(head):
        if c == "<":
            depth += 1
        elif c == ">":
            depth = max(0, depth - 1)
        elif c == "(" and depth == 0:
            start = k
            break
    if start is None:
        return "other", None
    name = r"((?:[A-Za-z_~][\w]*::)*(?:operator\s*[^\s(]+|~?[A-Za-z_]\w*))\s*$"
    m = re.search(name, head[:start])
    if not m:
        return "other", None
    return "function", m.group(1)


def functions(path):
    """(name, first line, last line) of every function body in the file."""
    with open(path, encoding="utf-8", errors="replace") as f:
        text = strip_preprocessor(blank_literals(f.read()))
    stack = []  # ('scope'|'function'|'other'|'init', name, start line)
    seg_start = 0
    found = []
    line = 1
    for k, c in enumerate(text):
        if c == "\n":
            line += 1
            continue
        if c not in "{};":
            continue
        inside_function = any(kind == "function" for kind, _, _ in stack)
        if c == "{":
            if inside_function or any(kind in ("other", "init") for kind, _, _ in stack):
                stack.append(("other", None, line))
            else:
                segment = text[seg_start:k]
                kind, name = classify(segment)
                first = line
                if kind == "function":
                    # The line of the name (the signature may wrap over several lines).
                    pos = segment.find(name.split("::")[-1] + "(")
                    if pos < 0:
                        pos = segment.find(name.split("::")[-1])
                    first = line - segment[max(pos, 0) :].count("\n")
                stack.append((kind, name, first))
                if kind == "init":
                    continue  # the constructor's signature goes on after the member's braces
            seg_start = k + 1
        elif c == "}":
            kind = None
            if stack:
                kind, name, first = stack.pop()
                if kind == "function":
                    found.append((name, first, line))
            if kind != "init":
                seg_start = k + 1
        elif c == ";" and not inside_function:
            seg_start = k + 1
    return found


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("paths", nargs="+", help="folders (searched recursively) or files")
    ap.add_argument("--max", type=int, default=120, help="longest allowed, lines (120)")
    ap.add_argument("--ext", default=".cpp,.hpp,.cc,.h", help="file name endings searched")
    args = ap.parse_args()
    exts = tuple(args.ext.split(","))
    files = []
    for p in args.paths:
        if os.path.isfile(p):
            files.append(p)
        elif os.path.isdir(p):
            for root, dirs, names in os.walk(p):
                dirs.sort()
                files += [os.path.join(root, f) for f in sorted(names) if f.endswith(exts)]
        else:
            print(f"long-functions: {p}: no such file or folder", file=sys.stderr)
            return 1
    rows = []
    for path in files:
        for name, first, last in functions(path):
            if last - first + 1 > args.max:
                rows.append((last - first + 1, path, first, name))
    for n, path, first, name in sorted(rows, key=lambda r: (-r[0], r[1], r[2])):
        print(f"{path}:{first}: {n} lines: {name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
