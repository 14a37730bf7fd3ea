"""Runs infra/statemachine.asl.json on moto's Step Functions engine for one job and compares its
image with `hort render --monolithic` (mode fused or staged), or checks that a job the Plan
function refuses ends FAILED with Hort.BadInput through PlanFailed (mode refused). Run by run.sh:

    EP=http://127.0.0.1:MOTO MODE=fused|staged|refused REPO=... OUT=... HORT_BIN=... python drive.py

moto 5.x's engine cannot run the definition as deployed; two rewrites, for moto only, each
with the line of moto that needs it, are below. What it cannot run at all (its ResultWriter
writes no result files, so the rerun loop always finds nothing lost; a Fail state cannot
re-raise a States.* error) is listed in infra/moto-sfn/README.md.
"""
import json, os, subprocess, sys, time, urllib.request
import boto3

ep, mode = os.environ["EP"], os.environ["MODE"]
repo = os.environ["REPO"]
scene_dir, main_file = f"{repo}/scenes/cornell", "cornell.json"
bucket, job = os.environ.get("BUCKET", "hort-moto-sfn"), f"moto-{mode}-{int(time.time())}"
if mode == "refused":  # a bucket the functions do not serve: Plan answers Hort.BadInput
    bucket = "other-bucket"
width, height, spp = 64, 48, 2
splits = 1 if mode == "fused" else 3
kw = dict(endpoint_url=ep, region_name="us-east-1", aws_access_key_id="testing",
          aws_secret_access_key="testing")
sfn, s3 = boto3.client("stepfunctions", **kw), boto3.client("s3", **kw)

req = urllib.request.Request(ep + "/moto-api/config", method="POST",
                             data=json.dumps({"stepfunctions": {"execute_state_machine": True}}).encode())
assert urllib.request.urlopen(req).status == 201

try:
    s3.create_bucket(Bucket=bucket)
except s3.exceptions.BucketAlreadyOwnedByYou:
    pass
for name in sorted(os.listdir(scene_dir)):
    if os.path.isfile(os.path.join(scene_dir, name)):
        s3.upload_file(os.path.join(scene_dir, name), bucket, f"jobs/{job}/scene/{name}")
request = {"scene": main_file,
           "render": {"width": width, "height": height, "spp": spp, "splits": splits, "spans": 4,
                      "split_mode": "spatial", **({"mode": mode} if mode != "refused" else {})},
           "max_concurrency": 2, "task_timeout_seconds": int(os.environ["TASK_TIMEOUT"]) if os.environ.get("TASK_TIMEOUT") else None}
s3.put_object(Bucket=bucket, Key=f"jobs/{job}/manifest.json", Body=json.dumps(request).encode())

defn = open(f"{repo}/infra/statemachine.asl.json").read()
# cargo lambda watch knows its functions by name only (an ARN: "that function doesn't exist as a
# binary"); lambda_proxy.py cuts ARNs to names, the no-proxy variant (FN_NAMES=1) passes names.
arn = "" if os.environ.get("FN_NAMES") else "arn:aws:lambda:us-east-1:123456789012:function:"
defn = defn.replace("${PlanFunctionArn}", arn + "plan").replace("${WorkerFunctionArn}", arn + "worker")
# moto 5.2.5's ASL grammar accepts only "STANDARD" here (ASLParser.execution_type).
n = defn.count('"ExecutionType": "EXPRESS"')
defn = defn.replace('"ExecutionType": "EXPRESS"', '"ExecutionType": "STANDARD"')
print(f"drive: {n} ItemProcessors rewritten EXPRESS -> STANDARD for moto's parser", file=sys.stderr)
# moto evaluates a ResultWriter's Parameters against the Map's results, not the state input
# (state_map.py:309, StringJsonPath reads env.stack[-1]): "$.bucket" is missing there, so the
# Map fails with States.Runtime. Literal values for this job instead: what Plan answers at
# $.plan.results (map_results_prefix, core/src/keys.rs).
d = json.loads(defn)
def literal_writers(states):
    for st in states.values():
        if "ResultWriter" in st:
            assert st["ResultWriter"]["Parameters"] == {"Bucket.$": "$.bucket", "Prefix.$": "$.plan.results"}
            st["ResultWriter"]["Parameters"] = {"Bucket": bucket, "Prefix": f"jobs/{job}/map-results"}
        if "ItemProcessor" in st:
            literal_writers(st["ItemProcessor"]["States"])
literal_writers(d["States"])
defn = json.dumps(d)
sm = sfn.create_state_machine(name=f"hort-{job}", definition=defn,
                              roleArn="arn:aws:iam::123456789012:role/sfn")["stateMachineArn"]
start = time.monotonic()
ex = sfn.start_execution(stateMachineArn=sm, input=json.dumps({"job": job, "bucket": bucket}))["executionArn"]
while (d := sfn.describe_execution(executionArn=ex))["status"] == "RUNNING":
    if time.monotonic() - start > float(os.environ.get("TIMEOUT", "900")):
        sys.exit("drive: execution still RUNNING")
    time.sleep(0.5)
hist, token = [], None
while True:
    page = sfn.get_execution_history(executionArn=ex, maxResults=1000, **({"nextToken": token} if token else {}))
    hist += page["events"]; token = page.get("nextToken")
    if not token: break
events = hist
out = os.path.join(os.environ["OUT"], mode)
os.makedirs(out, exist_ok=True)
json.dump(events, open(f"{out}/history.json", "w"), default=str, indent=1)
from collections import Counter
kinds = Counter(e["type"] for e in events)
print("drive: history:", {k: kinds[k] for k in ("TaskScheduled", "TaskSucceeded", "TaskFailed", "TaskTimedOut", "MapRunStarted", "MapRunSucceeded") if kinds[k]})
entered = [e["stateEnteredEventDetails"]["name"] for e in events if "stateEnteredEventDetails" in e]
print(f"drive: {mode} job {job}: {d['status']} in {time.monotonic() - start:.1f} s; states entered: "
      + " ".join(dict.fromkeys(entered)))
if mode == "refused":
    want = f'Plan failed: {{"errorType":"Hort.BadInput","errorMessage":"the event names bucket \\"{bucket}\\"'
    ok = d["status"] == "FAILED" and d.get("error") == "Hort.BadInput" and d.get("cause", "").startswith(want)
    print(f"drive: refused: {d['status']} {d.get('error')}: {d.get('cause')} -> {'as expected' if ok else 'UNEXPECTED'}")
    sys.exit(0 if ok else 1)
if d["status"] != "SUCCEEDED":
    for e in events[-int(os.environ.get("SHOW", "6")):]:
        det = {k: v for k, v in e.items() if k.endswith("EventDetails")}
        print("   ", e["id"], e["type"], json.dumps(det)[:700], file=sys.stderr)
    sys.exit(f"drive: {d.get('error')}: {d.get('cause')}")
plan = json.loads(d["output"])["plan"]
for field, key in plan["items"].items():
    items = json.loads(s3.get_object(Bucket=bucket, Key=key)["Body"].read())
    print(f"drive:   items {field}: {len(items)} (timeout_seconds {sorted(set(i.get('timeout_seconds') for i in items))})")
for run in sfn.list_map_runs(executionArn=ex)["mapRuns"]:
    m = sfn.describe_map_run(mapRunArn=run["mapRunArn"])
    print(f"drive:   map run {run['mapRunArn'].split(':')[-2]}: {m['status']}, maxConcurrency {m['maxConcurrency']}, items {m['itemCounts'].get('succeeded')}/{m['itemCounts'].get('total')}")
assert plan["mode"] == mode, plan
s3.download_file(bucket, f"jobs/{job}/out/image.pfm", f"{out}/moto-sfn.pfm")
subprocess.run([os.environ["HORT_BIN"], "render", f"{scene_dir}/{main_file}", "--width", str(width),
                "--height", str(height), "--spp", str(spp), "--monolithic", "--out", f"{out}/monolithic.pfm"],
               check=True, stdout=subprocess.DEVNULL)
same = open(f"{out}/moto-sfn.pfm", "rb").read() == open(f"{out}/monolithic.pfm", "rb").read()
print(f"drive: {mode}: image through moto's engine {'EQUALS' if same else 'DIFFERS FROM'} --monolithic "
      f"({os.path.getsize(out + '/moto-sfn.pfm')} bytes)")
sys.exit(0 if same else 1)
