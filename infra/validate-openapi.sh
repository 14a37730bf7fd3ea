#!/usr/bin/env bash
# Validates infra/openapi.yaml: against the OpenAPI 3 specification with openapi-spec-validator
# (from PyPI), then against the router it describes (functions/src/api/): the same routes and
# methods, the contract's statuses, and the same error codes.
#
#   bash infra/validate-openapi.sh
#
# Installs openapi-spec-validator 0.9.x into ${HORT_OPENAPI_VENV:-target/openapi-venv} the first
# time (needs python3 with venv and pip, and PyPI).
set -euo pipefail
cd "$(dirname "$0")/.."

venv="${HORT_OPENAPI_VENV:-target/openapi-venv}"
validator_spec='openapi-spec-validator>=0.9,<0.10'

if [ ! -x "$venv/bin/openapi-spec-validator" ]; then
    echo "validate-openapi: installing $validator_spec into $venv" >&2
    mkdir -p "$(dirname "$venv")"
    python3 -m venv "$venv"
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check "$validator_spec"
fi

"$venv/bin/openapi-spec-validator" infra/openapi.yaml

"$venv/bin/python" - infra/openapi.yaml functions/src/api/error.rs <<'PY'
import re
import sys

import yaml

spec_path, errors_path = sys.argv[1], sys.argv[2]
spec = yaml.safe_load(open(spec_path))
problems = []

# The routes and methods of functions/src/api/mod.rs.
routes = {
    "/": {"get"},
    "/renders": {"get", "post"},
    "/renders/{id}": {"get", "delete"},
    "/renders/{id}/image": {"get"},
    "/renders/{id}/frames/{k}/image": {"get"},
    "/renders/{id}/report": {"get"},
}
methods = {"get", "put", "post", "delete", "patch", "head", "options", "trace"}
described = {p: {m for m in ops if m in methods} for p, ops in spec["paths"].items()}
if described != routes:
    problems.append(f"paths and methods {described} are not the router's {routes}")

# The statuses of the contract.
expected = {
    ("/", "get"): {"200", "400", "405"},
    ("/renders", "get"): {"200", "400", "405"},
    ("/renders", "post"): {"200", "202", "400", "404", "405", "413", "415", "422", "429"},
    ("/renders/{id}", "get"): {"200", "404", "405"},
    ("/renders/{id}", "delete"): {"200", "404", "405"},
    ("/renders/{id}/image", "get"): {"200", "400", "404", "405"},
    ("/renders/{id}/frames/{k}/image", "get"): {"200", "400", "404", "405"},
    ("/renders/{id}/report", "get"): {"200", "404", "405"},
}
for (path, method), statuses in expected.items():
    have = set(spec["paths"].get(path, {}).get(method, {}).get("responses", {}))
    if not statuses <= have:
        problems.append(f"{method.upper()} {path} does not describe {sorted(statuses - have)}")

# The error codes of functions/src/api/error.rs.
source = open(errors_path).read()
codes = set(re.findall(r'StatusCode::\w+,\s*"([a-z_]+)"', source))
enum = set(spec["components"]["schemas"]["Error"]["properties"]["error"]["properties"]["code"]["enum"])
if not codes:
    problems.append(f"no error codes found in {errors_path}")
if codes != enum:
    problems.append(f"error codes {sorted(enum)} are not the router's {sorted(codes)}")

for p in problems:
    print(f"validate-openapi: {p}", file=sys.stderr)
if problems:
    sys.exit(1)
print(f"validate-openapi: {len(routes)} routes, {len(codes)} error codes agree with the router")
PY
