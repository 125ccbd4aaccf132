#!/usr/bin/env python3
"""Exit 0 when every `name==version` given is installed (used by .ci/run to skip the install)."""
import sys
from importlib.metadata import PackageNotFoundError, version

missing = []
for req in sys.argv[1:]:
    name, _, want = req.partition("==")
    try:
        have = version(name)
    except PackageNotFoundError:
        have = None
    if have is None or (want and have != want):
        missing.append("%s (have %s)" % (req, have))
if missing:
    print("missing: " + ", ".join(missing))
    sys.exit(1)
