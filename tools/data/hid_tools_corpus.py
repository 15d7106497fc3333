#!/usr/bin/python3
"""Writes a corpus of HID report descriptors, with the report sizes hid-tools' parser gives them.

Usage: /usr/bin/python3 tools/data/hid_tools_corpus.py HID_TOOLS_CHECKOUT FILE.py... > OUT.txt

HID_TOOLS_CHECKOUT is a copy of hid-tools (gitlab.freedesktop.org/libevdev/hid-tools); its
parser (hidtools/hid.py, ReportDescriptor.from_bytes, HidReport.bitsize) is the independent
reader, and needs python3-parse. Each FILE.py is one of its test files: the descriptors are the
literal byte lists and hex strings in it (a class's `report_descriptor`, a module-level list, a
call's `rdesc=`), found by reading the file's syntax tree, never by running it. Duplicates are
written once. The output is the format tests/devices_descriptor_files_test.cpp reads: per
descriptor `name:`, `rdesc:` (hex bytes) and `bits:` (TYPE ID BITS, the Report ID byte
included, ID 0 for a descriptor without IDs); a descriptor the parser refuses is left out and
named on standard error.
"""

import ast
import os
import sys


def hex_bytes(text):
    """The bytes of a string of hex pairs, or None when it is not one."""
    parts = text.split()
    if len(parts) < 8 or not all(len(p) == 2 for p in parts):
        return None
    try:
        return [int(p, 16) for p in parts]
    except ValueError:
        return None


def int_list(node):
    """The bytes of a literal list of integers, or None."""
    if not isinstance(node, ast.List) or len(node.elts) < 8:
        return None
    try:
        values = ast.literal_eval(node)
    except ValueError:
        return None
    if all(isinstance(v, int) and 0 <= v <= 255 for v in values):
        return values
    return None


def descriptors_in(path):
    """(name, bytes) for every descriptor literal in the file, in the order they appear."""
    tree = ast.parse(open(path, encoding="utf-8").read(), path)
    base = os.path.basename(path)
    found = []

    def visit(node, scope):
        if isinstance(node, ast.ClassDef):
            scope = node.name
        if isinstance(node, ast.Assign) and len(node.targets) == 1:
            target = node.targets[0]
            values = int_list(node.value)
            if values is not None and isinstance(target, ast.Name):
                name = target.id if target.id != "report_descriptor" else scope or target.id
                found.append((f"{base} {name}", values))
        if isinstance(node, ast.Call):
            device = None
            for kw in node.keywords:
                if kw.arg == "name" and isinstance(kw.value, ast.Constant):
                    device = kw.value.value
            for kw in node.keywords:
                if kw.arg in ("rdesc", "rdesc_str") and isinstance(kw.value, ast.Constant):
                    values = hex_bytes(str(kw.value.value))
                    if values is not None:
                        label = device or f"{scope or 'module'} line {kw.value.lineno}"
                        found.append((f"{base} {label}", values))
        for child in ast.iter_child_nodes(node):
            visit(child, scope)

    visit(tree, None)
    return found


def report_bits(parser, data):
    """Sorted (type, id, bits) of every report, as hid-tools' parser sizes them."""
    descriptor = parser.ReportDescriptor.from_bytes(data)
    out = []
    for kind, reports in (
        ("input", descriptor.input_reports),
        ("output", descriptor.output_reports),
        ("feature", descriptor.feature_reports),
    ):
        for report in reports.values():
            out.append((kind, max(report.report_ID, 0), report.bitsize))
    return sorted(out)


def main():
    if len(sys.argv) < 3 or sys.argv[1] in ("-h", "--help"):
        print(__doc__)
        return 0 if len(sys.argv) > 1 else 2
    sys.path.insert(0, sys.argv[1])
    import hidtools.hid as parser  # the checkout's own parser

    seen = set()
    written = 0
    for path in sys.argv[2:]:
        for name, data in descriptors_in(path):
            if tuple(data) in seen:
                continue
            seen.add(tuple(data))
            try:
                bits = report_bits(parser, data)
            except Exception as error:  # the independent reader refuses it: say so, skip it
                print(f"{name}: hid-tools refuses it: {error}", file=sys.stderr)
                continue
            print(f"name: {name}")
            print("rdesc: " + " ".join(f"{b:02x}" for b in data))
            print("bits: " + ", ".join(f"{k} {i} {n}" for k, i, n in bits))
            print()
            written += 1
    print(f"{written} descriptors", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
