#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""tools/long-functions.py on crafted C++ sources: each case names what the script must print
(the functions, their first line and length) and so fails when the brace matching or the
classification of a `{` changes."""

import argparse
import os
import subprocess
import sys
import tempfile
import textwrap
import unittest

SCRIPT = None


def run(source, max_lines=0, name="case.cpp"):
    """The script's rows on `source` as (name, first line, lines)."""
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, name)
        with open(path, "w", encoding="utf-8") as f:
            f.write(textwrap.dedent(source).lstrip("\n"))
        out = subprocess.run(
            [sys.executable, SCRIPT, "--max", str(max_lines), d],
            check=True,
            capture_output=True,
            text=True,
        ).stdout
    rows = []
    for line in out.splitlines():
        where, lines, name_part = line.split(": ", 2)
        rows.append((name_part.removeprefix("lines: "), int(where.rsplit(":", 1)[1]),
                     int(lines.split()[0])))
    return sorted(rows, key=lambda r: r[1])


class LongFunctions(unittest.TestCase):
    def test_counts_from_the_name_to_the_closing_brace(self):
        rows = run("""
            namespace a {
            int Short() { return 1; }
            double Wrapped(int first,
                           int second) {
                if (first) {
                    return second;
                }
                return 0;
            }
            }  // namespace a
            """)
        self.assertEqual(rows, [("Short", 2, 1), ("Wrapped", 3, 7)])

    def test_only_functions_longer_than_max_are_printed(self):
        body = "\n".join("    x += %d;" % k for k in range(10))
        source = "int Long(int x) {\n%s\n    return x;\n}\nint Small() { return 0; }\n" % body
        self.assertEqual(run(source, max_lines=5), [("Long", 1, 13)])
        self.assertEqual(run(source, max_lines=13), [])

    def test_tables_and_lambdas_at_namespace_scope_are_not_functions(self):
        rows = run("""
            const int kTable[] = {
                1,
                2,
            };
            const auto kTwice = [](int x) {
                return 2 * x;
            };
            struct Row {
                int id{0};
            };
            const Row kRows[] = {{1}, {2}};
            const std::string kName = Prefix("a") + std::string{"b"};
            """)
        self.assertEqual(rows, [])

    def test_braces_in_literals_and_comments_do_not_count(self):
        rows = run("""
            // a comment with a { brace
            const char* Text() {
                /* } */
                const char* s = "}}{";
                char c = '{';
                int n = 1'000;
                return R"x(a } b)x";
            }
            int After() { return 0; }
            """)
        self.assertEqual(rows, [("Text", 2, 7), ("After", 9, 1)])

    def test_lambdas_and_local_classes_belong_to_their_function(self):
        rows = run("""
            int Outer() {
                struct Local {
                    int Get() const { return 1; }
                };
                auto f = [&] {
                    return Local{}.Get();
                };
                return f();
            }
            """)
        self.assertEqual(rows, [("Outer", 1, 9)])

    def test_methods_constructors_and_operators(self):
        rows = run("""
            class Box {
            public:
                explicit Box(int v) : value_(v), other_{v} {
                    Check();
                }
                int value() const { return value_; }
            private:
                void Check();
                int value_, other_;
            };
            void Box::Check() {
                value_ += 0;
            }
            bool operator==(const Box& a, const Box& b) {
                return a.value() == b.value();
            }
            extern "C" {
            int c_entry(void) {
                return 0;
            }
            }
            """)
        self.assertEqual(rows, [("Box", 3, 3), ("value", 6, 1), ("Box::Check", 11, 3),
                                ("operator==", 14, 3), ("c_entry", 18, 3)])

    def test_a_missing_folder_is_an_error(self):
        r = subprocess.run([sys.executable, SCRIPT, "no/such/folder"], capture_output=True,
                           text=True)
        self.assertEqual(r.returncode, 1)
        self.assertIn("no/such/folder", r.stderr)


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--script", required=True)
    args, rest = ap.parse_known_args()
    SCRIPT = os.path.abspath(args.script)
    unittest.main(argv=[sys.argv[0]] + rest)
