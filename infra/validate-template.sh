#!/usr/bin/env bash
# Validates the deployment template (infra/template.yaml, or the files given) with cfn-lint
# (CloudFormation and SAM: schema, types, references, IAM policy syntax; it expands the SAM
# transform first), checkov (security checks) and `sam validate --lint` (the SAM CLI's own
# check: its SAM translator, then cfn-lint for us-east-1). All come from PyPI, installed once:
# cfn-lint and checkov into a venv under target/tools/cfn-venv, the SAM CLI (pinned) into
# target/tools/sam-venv beside it (its boto3 pin conflicts with checkov's); target/ is
# $CARGO_TARGET_DIR when set. HORT_CFN_VENV and HORT_SAM_VENV override the folders. Needs
# python3. Exit status 0 only if all three pass.
#
# Nothing here talks to AWS: `sam validate --lint` needs no credentials (only a region), its
# telemetry (on by default, sent to AWS) is off, and its weekly PyPI check for a newer SAM CLI is
# marked done: the version is pinned here.
#
# Every checkov suppression is in the template, next to the resource, with the reason. cfn-lint
# does not look inside the state machine's definition file: infra/validate-asl.sh does.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
tools="${CARGO_TARGET_DIR:-$here/../target}/tools"
venv="${HORT_CFN_VENV:-$tools/cfn-venv}"
sam_venv="${HORT_SAM_VENV:-$tools/sam-venv}"
cfn_lint_spec='cfn-lint>=1.58,<1.59'
specs=("$cfn_lint_spec" 'checkov>=3.3,<3.4')
sam_version='1.170.0'

if [[ ! -x "$venv/bin/cfn-lint" || ! -x "$venv/bin/checkov" ]]; then
    command -v python3 >/dev/null \
        || { echo "validate-template: python3 not found" >&2; exit 2; }
    echo "validate-template: installing ${specs[*]} into $venv" >&2
    mkdir -p "$(dirname "$venv")"
    python3 -m venv "$venv"
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check "${specs[@]}" >&2
fi

sam_installed() {
    [[ -x "$sam_venv/bin/sam" ]] && [[ "$("$sam_venv/bin/python" -c \
        'import importlib.metadata as m; print(m.version("aws-sam-cli"))' 2>/dev/null)" == "$sam_version" ]]
}
if ! sam_installed; then
    command -v python3 >/dev/null \
        || { echo "validate-template: python3 not found" >&2; exit 2; }
    # The same cfn-lint line as above, so both lint runs apply the same rules.
    echo "validate-template: installing aws-sam-cli==$sam_version ($cfn_lint_spec) into $sam_venv" >&2
    mkdir -p "$(dirname "$sam_venv")"
    python3 -m venv "$sam_venv"
    "$sam_venv/bin/python" -m pip install --quiet --disable-pip-version-check \
        "aws-sam-cli==$sam_version" "$cfn_lint_spec" >&2
    sam_installed || { echo "validate-template: aws-sam-cli $sam_version did not install" >&2; exit 1; }
fi
# The SAM CLI keeps its state (metadata.json: installation id, last version check) in the venv
# rather than ~/.aws-sam (__SAM_CLI_APP_DIR, the SAM CLI's own override of that folder); the
# last version check is set to 2100 (a float: SAM ignores an integer) so it never asks PyPI for
# a newer version.
export SAM_CLI_TELEMETRY=0 __SAM_CLI_APP_DIR="$sam_venv/sam-app-dir"
if [[ ! -f "$__SAM_CLI_APP_DIR/metadata.json" ]]; then
    mkdir -p "$__SAM_CLI_APP_DIR"
    echo '{"lastVersionCheck": 4102444800.0}' >"$__SAM_CLI_APP_DIR/metadata.json"
fi

if [[ $# -eq 0 ]]; then
    set -- "$here/template.yaml"
fi

echo "validate-template: cfn-lint $("$venv/bin/cfn-lint" --version | awk '{print $NF}')"
"$venv/bin/cfn-lint" -- "$@"
echo "validate-template: cfn-lint passed"

echo "validate-template: checkov $("$venv/bin/checkov" --version)"
for file in "$@"; do
    # --framework cloudformation covers SAM resources; no network: no Bridgecrew API key, no
    # version check, no download of external checks.
    BC_SKIP_MAPPING=TRUE CHECKOV_RUN_SCA_PACKAGE_SCAN_V2=false \
        "$venv/bin/checkov" --quiet --compact --framework cloudformation \
        --skip-download -f "$file"
done
echo "validate-template: checkov passed"

echo "validate-template: sam validate --lint, SAM CLI $sam_version ($sam_venv)"
for file in "$@"; do
    "$sam_venv/bin/sam" validate --lint --region us-east-1 --template "$file"
done
echo "validate-template: sam validate --lint passed"
