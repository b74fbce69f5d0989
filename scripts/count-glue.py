#!/usr/bin/env python3
"""Counts the property and glue lines of each element in gst/elements: the PROP_ enum, the
set_property, get_property and finalize functions (and install_* helpers), the flag macros, and
in class_init the statements that install properties or set those vfuncs. Prints one line per
element, the shared property code (properties.*), the totals and gst/elements' line count.

Usage: scripts/count-glue.py [DIR]   (DIR defaults to gst/elements of this checkout)"""
import pathlib
import re
import sys

ELEMENTS = ["exgsegment", "siftmatch", "spraycontrol", "stereodepth", "stereorectify",
            "treecamerasrc", "treemetrics", "treeoverlay", "treetestsrc"]
GLUE_FUNCTION = re.compile(r"^static .*\b\w*(_set_property|_get_property|_finalize|install_\w+)\(")
GLUE_STATEMENT = re.compile(r"install_property|g_param_spec_|install_\w+\(|PropertyTable|props\.|"
                            r"->set_property|->get_property|->finalize|GParamFlags")


def block_end(lines, i, closing):
    while not lines[i].startswith(closing):
        i += 1
    return i


def count(path):
    lines = path.read_text().splitlines()
    n, i = 0, 0
    while i < len(lines):
        line = lines[i]
        if line.startswith("enum {") and "PROP_0" in lines[i + 1]:
            j = block_end(lines, i, "};")
            n += j - i + 1
            i = j + 1
        elif re.match(r"#define (RW_\w+|RO|PROP_FLAGS)\b", line):
            j = i
            while lines[j].endswith("\\"):
                j += 1
            n += j - i + 1
            i = j + 1
        elif GLUE_FUNCTION.match(line):
            j = block_end(lines, i, "}")
            n += j - i + 1
            i = j + 1
        elif re.match(r"^static void \w+_class_init\(", line):
            end = block_end(lines, i, "}")
            j = i + 2
            while j < end:
                k, text = j, lines[j]
                while not (lines[k].rstrip().endswith(";") and text.count("(") == text.count(")")) \
                        and k + 1 < end:
                    k += 1
                    text += "\n" + lines[k]
                if GLUE_STATEMENT.search(text):
                    n += k - j + 1
                j = k + 1
            i = end + 1
        else:
            i += 1
    return n, len(lines)


def main():
    root = pathlib.Path(sys.argv[1]) if len(sys.argv) > 1 else \
        pathlib.Path(__file__).resolve().parent.parent / "gst" / "elements"
    total_glue = total_lines = 0
    print(f"{'element':<16}{'glue':>6}{'lines':>7}")
    for name in ELEMENTS:
        glue, lines = count(root / f"{name}.cpp")
        total_glue += glue
        total_lines += lines
        print(f"{name:<16}{glue:>6}{lines:>7}")
    shared = sum(len(p.read_text().splitlines()) for p in sorted(root.glob("properties.*")))
    print(f"{'properties.*':<16}{shared:>6}")
    print(f"{'total glue':<16}{total_glue + shared:>6}")
    all_lines = sum(len(p.read_text().splitlines())
                    for p in root.iterdir() if p.suffix in (".cpp", ".hpp"))
    print(f"{'gst/elements':<16}{all_lines:>6}")


if __name__ == "__main__":
    main()
