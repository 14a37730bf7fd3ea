#!/usr/bin/env bash
# Installs the AWS SAM CLI (pinned) from PyPI into a venv under target/tools/sam-venv
# ($CARGO_TARGET_DIR/tools/sam-venv when CARGO_TARGET_DIR is set; HORT_SAM_VENV overrides the
# folder), once, and prints the path of `sam-offline`, a wrapper that runs it without talking to
# AWS:
#
#   sam="$(bash infra/install-sam-cli.sh)"
#   "$sam" validate --lint --region us-east-1 --template infra/template.yaml
#
# The wrapper turns telemetry off (on by default, sent to AWS) and keeps the SAM CLI's state
# (metadata.json) in the venv instead of ~/.aws-sam (__SAM_CLI_APP_DIR, the SAM CLI's own
# override of that folder), with its weekly check for a newer version marked done until 2100 (a
# float: SAM ignores an integer): the version is pinned here. Its cfn-lint is the one
# infra/validate-template.sh pins, so both lint runs apply the same rules. Needs python3 (venv).
set -euo pipefail

version='1.170.0'
cfn_lint_spec='cfn-lint>=1.58,<1.59'
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
venv="${HORT_SAM_VENV:-${CARGO_TARGET_DIR:-$here/../target}/tools/sam-venv}"

installed() {
    [[ -x "$venv/bin/sam-offline" ]] && [[ "$("$venv/bin/python" -c \
        'import importlib.metadata as m; print(m.version("aws-sam-cli"))' 2>/dev/null)" == "$version" ]]
}

if ! installed; then
    command -v python3 >/dev/null \
        || { echo "install-sam-cli: python3 not found" >&2; exit 2; }
    echo "install-sam-cli: installing aws-sam-cli==$version ($cfn_lint_spec) into $venv" >&2
    mkdir -p "$(dirname "$venv")"
    python3 -m venv "$venv"
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check \
        "aws-sam-cli==$version" "$cfn_lint_spec" >&2
    venv="$(cd "$venv" && pwd)"
    mkdir -p "$venv/sam-app-dir"
    echo '{"lastVersionCheck": 4102444800.0}' >"$venv/sam-app-dir/metadata.json"
    cat >"$venv/bin/sam-offline" <<WRAPPER
#!/usr/bin/env bash
# The SAM CLI without telemetry or version checks (written by infra/install-sam-cli.sh).
export SAM_CLI_TELEMETRY=0 __SAM_CLI_APP_DIR="$venv/sam-app-dir"
exec "$venv/bin/sam" "\$@"
WRAPPER
    chmod +x "$venv/bin/sam-offline"
    installed || { echo "install-sam-cli: aws-sam-cli $version did not install" >&2; exit 1; }
fi
echo "$(cd "$venv" && pwd)/bin/sam-offline"
