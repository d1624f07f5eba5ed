#!/usr/bin/env python3
"""Reads a JUnit XML report with `junitparser` (PyPI), an independent reader, and prints what
it holds as JSON: every test case with its result, and the failures' types and messages.
Used by the tests of `stairbench regress` (tests/regress.rs)."""
import json
import sys

from junitparser import Failure, JUnitXml


def main(path):
    xml = JUnitXml.fromfile(path)
    cases = []
    for suite in xml:
        for case in suite:
            failure = next((r for r in case.result if isinstance(r, Failure)), None)
            cases.append({
                "suite": suite.name,
                "name": case.name,
                "classname": case.classname,
                "passed": failure is None and not case.result,
                "type": failure.type if failure is not None else None,
                "message": failure.message if failure is not None else None,
                "system_out": case.system_out or "",
            })
    print(json.dumps({"tests": len(cases), "failures": sum(not c["passed"] for c in cases), "cases": cases}))


if __name__ == "__main__":
    main(sys.argv[1])
