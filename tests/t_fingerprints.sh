#!/usr/bin/env bash
# Result fingerprints: every dataset (name, type, shape, units, description, bytes) of a varied set of rings,
# corridors and a sweep must equal tests/fingerprint/expected.txt. Results are a contract: a deliberate change
# of results rewrites that file with `tests/fingerprint/fingerprint.py update` and is named in the change.
set -u
cd "$(dirname "$0")/.."
exec /usr/bin/python3 tests/fingerprint/fingerprint.py check
