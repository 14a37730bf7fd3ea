#!/usr/bin/env bash
# Validates the deployment template (infra/template.yaml, or the files given) with cfn-lint
# (CloudFormation and SAM: schema, types, references, IAM policy syntax; it expands the SAM
# transform first), checkov (security checks) and `sam validate --lint` (the SAM CLI's own
# check: its SAM translator, then cfn-lint for us-east-1). All come from PyPI, installed once:
# cfn-lint and checkov into a venv under target/tools/cfn-venv, the SAM CLI (pinned) into
# target/tools/sam-venv beside it by infra/install-sam-cli.sh (its boto3 pin conflicts with
# checkov's); target/ is $CARGO_TARGET_DIR when set. HORT_CFN_VENV and HORT_SAM_VENV override
# the folders. Needs python3. Exit status 0 only if all three pass.
#
# Nothing here talks to AWS: `sam validate --lint` needs no credentials (only a region), and
# the SAM CLI runs without telemetry or version checks (see infra/install-sam-cli.sh).
#
# Every checkov suppression is in the template, next to the resource, with the reason. cfn-lint
# does not look inside the state machine's definition file: infra/validate-asl.sh does.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
tools="${CARGO_TARGET_DIR:-$here/../target}/tools"
venv="${HORT_CFN_VENV:-$tools/cfn-venv}"
# infra/install-sam-cli.sh pins the same cfn-lint for the SAM CLI.
specs=('cfn-lint>=1.58,<1.59' 'checkov>=3.3,<3.4')

if [[ ! -x "$venv/bin/cfn-lint" || ! -x "$venv/bin/checkov" ]]; then
    command -v python3 >/dev/null \
        || { echo "validate-template: python3 not found" >&2; exit 2; }
    echo "validate-template: installing ${specs[*]} into $venv" >&2
    mkdir -p "$(dirname "$venv")"
    python3 -m venv "$venv"
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check "${specs[@]}" >&2
fi

sam="$(bash "$here/install-sam-cli.sh")"

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

echo "validate-template: sam validate --lint ($sam)"
for file in "$@"; do
    "$sam" validate --lint --region us-east-1 --template "$file"
done
echo "validate-template: sam validate --lint passed"
