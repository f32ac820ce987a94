"""Test-wide setup: the public API's shape annotations are checked on every call the tests make.

``shape_checks.install`` wraps the public functions of ``jaxbill`` before any
test module imports them, so ``jb.orbit(...)`` and ``from jaxbill import orbit``
both get the checked version. ``test_shape_checks.py`` proves the checks are live.
"""

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import jaxbill
import shape_checks

UNRESOLVED_ANNOTATIONS = shape_checks.install(jaxbill)
