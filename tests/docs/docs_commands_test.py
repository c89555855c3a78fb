#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Every command shown in the user docs runs, and every option it shows exists.

The convention (docs/development.md, "Documented commands"), for the fenced blocks of the
documents given (README.md, docs/user-guide.md, docs/reference.md by default):

  ```sh            run, in order, with bash -e -o pipefail, in a work folder of its own per
                   document whose build/bin is the build's bin folder;
  <!-- not-run: reason -->
  ```sh            not run (installing, services, commands that serve until stopped); listed
                   with its reason;
  ```text          a general form with placeholders (LOGDIR, P, ...): not run;
  <!-- output-of: pitmap ARGS -->
  ```yaml          must be exactly what `pitmap ARGS` prints (--update rewrites it).

In every sh and text block, each long option given to a pitmap program (build/bin/pitmap-*,
with its subcommand) must appear in that program's --help, and every path into the source tree
(tools/..., firmware_host/...) must exist. Exit status 1 on the first failing command of a
document or on any other problem, with what and where.
"""

import argparse
import os
import re
import shlex
import subprocess
import sys
import tempfile
import time

DEFAULT_DOCS = ["README.md", "docs/user-guide.md", "docs/reference.md", "docs/cli.md",
                "docs/packages.md", "docs/report.md", "docs/georeferencing.md",
                "docs/benchmarks.md", "docs/echo_artifacts.md", "docs/compare.md",
                "docs/campaigns.md"]
LINKED_DOCS = DEFAULT_DOCS + ["docs/development.md", "docs/accuracy.md"]
MARKER = re.compile(r"^<!--\s*(not-run|output-of):\s*(.*?)\s*-->$")
FENCE = re.compile(r"^```(\S*)\s*$")
PROGRAM = re.compile(r"^(?:\./)?(?:build/bin/)?(pitmap(?:-[a-z0-9_]+)*)$")
REPO_PATH = re.compile(r"^(?:tools|firmware_host|processor|common|tests|docs|lcmtypes)/[^*?]+$")
OPERATORS = {";", "&&", "||", "|", "&", ">", ">>", "<", "2>", "(", ")"}


class Block:
    def __init__(self, doc, line, lang, text, marker, start, end):
        self.doc, self.line, self.lang, self.text = doc, line, lang, text
        self.marker = marker  # (kind, argument) or None
        self.start, self.end = start, end  # line indices of the fences in the document

    def where(self):
        return f"{self.doc}:{self.line}"


def parse_blocks(doc, text):
    """The fenced blocks of a Markdown text, each with the marker comment just above it."""
    lines = text.split("\n")
    blocks, i = [], 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        j = i + 1
        while j < len(lines) and lines[j].rstrip() != "```":
            j += 1
        if j == len(lines):
            raise SystemExit(f"{doc}:{i + 1}: a fenced block that is never closed")
        k = i - 1
        while k >= 0 and not lines[k].strip():
            k -= 1
        mk = MARKER.match(lines[k].strip()) if k >= 0 else None
        marker = (mk.group(1), mk.group(2)) if mk else None
        body = "\n".join(lines[i + 1:j]) + ("\n" if j > i + 1 else "")
        blocks.append(Block(doc, i + 1, m.group(1), body, marker, i, j))
        i = j + 1
    return blocks


def logical_lines(text):
    """Lines with their backslash continuations joined."""
    out, cur = [], ""
    for line in text.split("\n"):
        if line.rstrip().endswith("\\"):
            cur += line.rstrip()[:-1] + " "
        else:
            out.append(cur + line)
            cur = ""
    if cur:
        out.append(cur)
    return [line for line in out if line.strip()]


def commands(line):
    """The simple commands of a shell line, as token lists (comments and operators dropped)."""
    lex = shlex.shlex(line, posix=True, punctuation_chars=True)
    lex.whitespace_split = True
    lex.commenters = "#"
    result, cur = [], []
    for tok in lex:
        if tok in OPERATORS or set(tok) <= set(";&|<>()"):
            if cur:
                result.append(cur)
            cur = []
            if tok in (">", ">>", "<", "2>"):
                cur = ["<redirect>"]
        else:
            cur.append(tok)
    if cur:
        result.append(cur)
    return [c for c in result if c and c[0] != "<redirect>"]


class Helps:
    """--help of each program and subcommand, asked once."""

    def __init__(self, bindir):
        self.bindir, self.cache = bindir, {}

    def text(self, prog, sub=None):
        key = (prog, sub)
        if key not in self.cache:
            exe = os.path.join(self.bindir, prog)
            if not os.access(exe, os.X_OK):
                self.cache[key] = None
            else:
                argv = [exe] + ([sub] if sub else []) + ["--help"]
                r = subprocess.run(argv, capture_output=True, text=True, timeout=120)
                self.cache[key] = r.stdout + r.stderr
        return self.cache[key]

    def subcommands(self, prog):
        text = self.text(prog) or ""
        m = re.search(r"^Subcommands:\n((?:  .*\n?)+)", text, re.M)
        return {line.split()[0] for line in m.group(1).splitlines()} if m else set()


def option_of(token):
    t = token.strip("[]")
    if not t.startswith("--") or len(t) < 3:
        return None
    return t.split("=", 1)[0].rstrip(",.:;")


def check_block(block, helps, source):
    """Problems with the options and repository paths of one sh/text block."""
    problems, checked = [], 0
    for line in logical_lines(block.text):
        try:
            cmds = commands(line)
        except ValueError as e:
            problems.append(f"{block.where()}: cannot read the line ({e}): {line.strip()}")
            continue
        for cmd in cmds:
            for tok in cmd:
                path = tok.strip("[]")
                if REPO_PATH.match(path) and not os.path.exists(os.path.join(source, path)):
                    problems.append(f"{block.where()}: '{path}' is not in the source tree")
            m = PROGRAM.match(cmd[0])
            if not m:
                continue
            prog, args = m.group(1), cmd[1:]
            if helps.text(prog) is None:
                problems.append(f"{block.where()}: program '{prog}' is not in {helps.bindir}")
                continue
            sub = None
            if args and not args[0].startswith("-") and args[0] in helps.subcommands(prog):
                sub = args[0]
                args = args[1:]
            elif args and re.fullmatch(r"[a-z]+", args[0]) and \
                    helps.text(f"{prog}-{args[0]}") is not None:
                prog = f"{prog}-{args[0]}"  # `pitmap live` runs the program pitmap-live
                args = args[1:]
            help_text = helps.text(prog, sub) or ""
            for tok in args:
                opt = option_of(tok)
                if opt is None:
                    continue
                checked += 1
                if not re.search(r"(?<![\w-])" + re.escape(opt) + r"(?![\w-])", help_text):
                    name = prog + (" " + sub if sub else "")
                    problems.append(f"{block.where()}: '{name}' has no option {opt} "
                                    f"(not in `{name} --help`)")
    return problems, checked


def output_of(block, bindir):
    argv = shlex.split(block.marker[1])
    m = PROGRAM.match(argv[0]) if argv else None
    if not m:
        return None, f"{block.where()}: output-of names no pitmap program: {block.marker[1]}"
    r = subprocess.run([os.path.join(bindir, m.group(1))] + argv[1:], capture_output=True,
                       text=True, timeout=120)
    if r.returncode != 0:
        return None, f"{block.where()}: `{block.marker[1]}` failed ({r.returncode}): {r.stderr}"
    return r.stdout, None


def run_block(block, workdir, log):
    start = time.monotonic()
    with open(log, "a") as out:
        out.write(f"\n===== {block.where()}\n{block.text}=====\n")
        out.flush()
        r = subprocess.run(["bash", "-e", "-o", "pipefail", "-c", block.text], cwd=workdir,
                           stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                           timeout=900)
    return r.returncode, time.monotonic() - start


def tail(path, n=40):
    with open(path, errors="replace") as f:
        return "".join(f.readlines()[-n:])


def check_docs(source, bindir, docs, work, update=False, run=True):
    """Every check on every document; returns the list of problems (empty = pass)."""
    helps = Helps(bindir)
    problems = []
    for doc in docs:
        path = os.path.join(source, doc)
        with open(path) as f:
            text = f.read()
        blocks = parse_blocks(doc, text)
        ran = not_run = general = outputs = options = 0
        # output-of blocks first: they may be rewritten
        lines = text.split("\n")
        for b in reversed([b for b in blocks if b.marker and b.marker[0] == "output-of"]):
            outputs += 1
            got, err = output_of(b, bindir)
            if err:
                problems.append(err)
            elif got != b.text:
                if update:
                    lines[b.start + 1:b.end] = got.rstrip("\n").split("\n")
                else:
                    problems.append(f"{b.where()}: the block is not what `{b.marker[1]}` prints "
                                    f"now; run {os.path.basename(__file__)} --update")
        if update:
            new = "\n".join(lines)
            if new != text:
                with open(path, "w") as f:
                    f.write(new)
                print(f"{doc}: output-of blocks rewritten")
        to_run = []
        for b in blocks:
            if b.lang not in ("sh", "text"):
                continue
            if b.marker and b.marker[0] == "not-run":
                if b.lang != "sh":
                    problems.append(f"{b.where()}: not-run marks an sh block only")
                if not b.marker[1]:
                    problems.append(f"{b.where()}: not-run without a reason")
                not_run += 1
                print(f"{b.where()}: not run: {b.marker[1]}")
            elif b.lang == "sh":
                to_run.append(b)
            else:
                general += 1
            p, n = check_block(b, helps, source)
            problems += p
            options += n
        if run and to_run:
            workdir = os.path.join(work, doc.replace("/", "_"))
            subprocess.run(["rm", "-rf", workdir], check=True)
            os.makedirs(os.path.join(workdir, "build"))
            os.symlink(os.path.abspath(bindir), os.path.join(workdir, "build", "bin"))
            log = os.path.join(workdir, "commands.log")
            for b in to_run:
                rc, seconds = run_block(b, workdir, log)
                print(f"{b.where()}: ran {len(logical_lines(b.text))} line(s) in {seconds:.1f} s"
                      f"{'' if rc == 0 else f': exit status {rc}'}")
                if rc != 0:
                    problems.append(f"{b.where()}: a documented command failed (exit status {rc});"
                                    f" the end of {log}:\n{tail(log)}")
                    break  # the later blocks of this document build on it
                ran += 1
        print(f"{doc}: {ran} sh block(s) run, {not_run} not run, {general} text block(s), "
              f"{outputs} output-of block(s), {options} option(s) checked against --help")
    return problems


def anchors(text):
    """GitHub's anchors of a Markdown text's headings (outside fenced blocks)."""
    result, fenced = set(), False
    for line in text.split("\n"):
        if line.startswith("```"):
            fenced = not fenced
        m = None if fenced else re.match(r"^#{1,6}\s+(.*?)\s*$", line)
        if m:
            a = re.sub(r"[^\w\- ]", "", m.group(1).lower()).replace(" ", "-")
            n, base = 1, a
            while a in result:
                a, n = f"{base}-{n}", n + 1
            result.add(a)
    return result


def check_links(source, docs):
    """Relative links of the documents: the file exists and, for a Markdown file, the anchor."""
    problems = []
    for doc in docs:
        count = 0
        with open(os.path.join(source, doc)) as f:
            text = f.read()
        prose = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)
        for m in re.finditer(r"\]\(([^)\s]+)\)", prose):
            target = m.group(1)
            if re.match(r"^[a-z]+:", target):
                continue  # http:, https:, mailto:
            count += 1
            path, _, anchor = target.partition("#")
            full = os.path.normpath(os.path.join(source, os.path.dirname(doc), path)) if path \
                else os.path.join(source, doc)
            if not os.path.exists(full):
                problems.append(f"{doc}: link to {target}: no such file")
            elif anchor and full.endswith(".md"):
                with open(full) as f:
                    if anchor not in anchors(f.read()):
                        problems.append(f"{doc}: link to {target}: no such heading")
        print(f"{doc}: {count} relative link(s) checked")
    return problems


SELF_TEST_DOC = """# fixture

```sh
build/bin/pitmap config --defaults > defaults.yaml
```

<!-- not-run: a flag that does not exist -->
```sh
build/bin/pitmap run LOGDIR --out P --no-such-flag
```

```text
build/bin/pitmap-sim synth --scenario demo --out DIR --vendor-file
tools/no-such-script.sh
```

<!-- output-of: pitmap config --vehicle -->
```yaml
pitmap_vehicle: 2
```

```sh
build/bin/pitmap info no-such-log.lcmlog
```

```sh
echo never reached > reached.txt
```
"""


def self_test(bindir, work):
    """The checks find what they are for: a bogus option, a missing script, a stale output
    block and a failing command (which stops the document)."""
    src = tempfile.mkdtemp(dir=work)
    with open(os.path.join(src, "fixture.md"), "w") as f:
        f.write(SELF_TEST_DOC)
    problems = check_docs(src, bindir, ["fixture.md"], work)
    expected = ["'pitmap run' has no option --no-such-flag",
                "'pitmap-sim synth' has no option --vendor-file",
                "'tools/no-such-script.sh' is not in the source tree",
                "is not what `pitmap config --vehicle` prints",
                "fixture.md:22: a documented command failed"]
    failed = False
    for e in expected:
        if not any(e in p for p in problems):
            print(f"self-test: not detected: {e}")
            failed = True
    if len(problems) != len(expected):
        print(f"self-test: {len(problems)} problems for {len(expected)} planted:\n  " +
              "\n  ".join(problems))
        failed = True
    if os.path.exists(os.path.join(work, "fixture.md", "reached.txt")):
        print("self-test: a block after a failed one was run")
        failed = True
    if not os.path.exists(os.path.join(work, "fixture.md", "defaults.yaml")):
        print("self-test: the first block did not run")
        failed = True
    # --update rewrites the stale block, then the document checks clean but for the rest.
    check_docs(src, bindir, ["fixture.md"], work, update=True, run=False)
    after = check_docs(src, bindir, ["fixture.md"], work, run=False)
    if any("config --vehicle" in p for p in after):
        print("self-test: --update did not rewrite the output-of block")
        failed = True
    # Links: a missing file and a missing heading are found, good ones pass.
    with open(os.path.join(src, "links.md"), "w") as f:
        f.write("# Links\n\n## The report's 3D view\n\n[a](#the-reports-3d-view) "
                "[b](fixture.md#fixture) [c](#no-such-heading) [d](no-such-file.md) "
                "[e](https://example.org/x)\n```text\n[f](not-a-link.md)\n```\n")
    links = check_links(src, ["links.md"])
    if sorted(links) != ["links.md: link to #no-such-heading: no such heading",
                         "links.md: link to no-such-file.md: no such file"]:
        print("self-test: link check found", links)
        failed = True
    print("self-test:", "FAILED" if failed else "every planted problem found")
    return 1 if failed else 0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--source", default=os.path.join(os.path.dirname(__file__), "..", ".."),
                    help="source tree (default: this script's)")
    ap.add_argument("--bin", required=True, help="the build's bin folder (build/bin)")
    ap.add_argument("--work", help="work folder (default: a new temporary one)")
    ap.add_argument("--docs", nargs="+", default=DEFAULT_DOCS, help="documents, from --source")
    ap.add_argument("--update", action="store_true", help="rewrite the output-of blocks")
    ap.add_argument("--no-run", action="store_true", help="check options and outputs only")
    ap.add_argument("--self-test", action="store_true", help="check the checker on a fixture")
    ap.add_argument("--links", action="store_true",
                    help="check only the relative links (files and headings) of the documents")
    a = ap.parse_args()
    work = a.work or tempfile.mkdtemp(prefix="pitmap-docs-")
    os.makedirs(work, exist_ok=True)
    if a.self_test:
        return self_test(a.bin, work)
    start = time.monotonic()
    if a.links:
        problems = check_links(a.source, a.docs if a.docs != DEFAULT_DOCS else LINKED_DOCS)
        for p in problems:
            print("PROBLEM:", p)
        return 1 if problems else 0
    problems = check_docs(a.source, a.bin, a.docs, work, update=a.update,
                          run=not (a.no_run or a.update))
    for p in problems:
        print("PROBLEM:", p)
    print(f"docs: {len(problems)} problem(s) in {time.monotonic() - start:.0f} s; work in {work}")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
