"""none-skipped.py REPORT WHAT: a suite that must run every test (vcan, ROS 2, browser) passes only when its
pytest JUnit report counts at least one test and no skip. Read from pytest's own report, not its console
text; one rule for the three scripts that run such suites. Exit 1 with a line saying why otherwise."""

import sys
import xml.etree.ElementTree as ET

report, what = sys.argv[1], sys.argv[2]
try:
    root = ET.parse(report).getroot()
except (OSError, ET.ParseError) as exc:
    sys.exit(f"{what}: no pytest report ({exc})")
suites = [root] if root.tag == "testsuite" else list(root.iter("testsuite"))
tests = sum(int(s.get("tests", 0)) for s in suites)
skipped = sum(int(s.get("skipped", 0)) for s in suites)
if tests == 0:
    sys.exit(f"{what}: no test ran")
if skipped:
    sys.exit(f"{what}: {skipped} of {tests} tests skipped: refused (all must run here)")
print(f"{what}: {tests} tests ran, none skipped")
