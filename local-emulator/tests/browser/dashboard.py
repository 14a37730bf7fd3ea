"""Drives headless Chromium through the DevTools protocol against a running `hort serve`:
opens the dashboard, submits the bundled Cornell box from the page's form (dry run first),
waits for the image to appear, checks the DOM, submits a job whose scene is named
`<script>...` and checks that it shows as text, and takes a screenshot.

Usage: dashboard.py DEVTOOLS_PORT HORT_URL SCREENSHOT_PATH
Prints one line per check and `N passed, M failed`; exits non-zero if any check failed.
"""

import base64
import json
import sys
import time
import urllib.request

import websocket  # websocket-client, from PyPI

devtools_port, hort_url, screenshot = sys.argv[1], sys.argv[2], sys.argv[3]
results = []


def check(name, ok, detail=""):
    results.append(ok)
    print(f"browser: {'ok  ' if ok else 'FAIL'} {name}{': ' + str(detail) if detail else ''}",
          flush=True)


class Page:
    def __init__(self, ws_url):
        self.ws = websocket.create_connection(ws_url, timeout=30)
        self.next_id = 0

    def call(self, method, **params):
        self.next_id += 1
        self.ws.send(json.dumps({"id": self.next_id, "method": method, "params": params}))
        while True:
            msg = json.loads(self.ws.recv())
            if msg.get("id") == self.next_id:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg["result"]

    def js(self, expression):
        r = self.call("Runtime.evaluate", expression=expression, returnByValue=True,
                      awaitPromise=True)
        if "exceptionDetails" in r:
            raise RuntimeError(f"{expression}: {r['exceptionDetails']}")
        return r["result"].get("value")

    def wait(self, expression, limit, what):
        deadline = time.time() + limit
        while time.time() < deadline:
            value = self.js(expression)
            if value:
                return value
            time.sleep(0.2)
        raise RuntimeError(f"timed out after {limit} s waiting for {what}")


req = urllib.request.Request(f"http://127.0.0.1:{devtools_port}/json/new?about:blank",
                             method="PUT")
target = json.load(urllib.request.urlopen(req, timeout=30))
page = Page(target["webSocketDebuggerUrl"])
page.call("Page.enable")
# The page is the one in front, so its timers run at full rate.
page.call("Page.bringToFront")
page.call("Emulation.setFocusEmulationEnabled", enabled=True)
page.call("Emulation.setDeviceMetricsOverride", width=1280, height=900, deviceScaleFactor=1,
          mobile=False)
page.call("Page.navigate", url=hort_url)
page.wait("document.readyState === 'complete' && !!document.getElementById('scene')", 30,
          "the page to load")
check("page title", page.js("document.title") == "HORT renders", page.js("document.title"))

# The form: the bundled Cornell box, 64x48, 2 spp, 2 splits; a dry run first.
page.js("""(() => {
  document.getElementById('scene').value = 'cornell';
  for (const [id, v] of [['width', 64], ['height', 48], ['spp', 2], ['splits', 2]])
    document.getElementById(id).value = v;
  document.getElementById('dry-run').click();
})()""")
answer = page.wait("(t => t.startsWith('dry run') && t)(document.getElementById('answer')"
                   ".textContent)", 30, "the dry run's answer")
check("dry run shows the predicted time and cost",
      "64x48, 2 spp, 2 splits" in answer and "predicted" in answer and "$" in answer, answer)
check("a dry run starts no job",
      page.js("fetch('renders').then(r => r.json()).then(v => v.renders.length)") == 0)

page.js("document.getElementById('render').click()")
job = page.wait("(m => m && m[1])(document.getElementById('answer').textContent"
                ".match(/^submitted (\\S+)/))", 30, "the submission's answer")
print(f"browser: submitted {job} from the page", flush=True)
row = f"document.querySelector('#jobs tr[data-job=\"{job}\"]')"
page.wait(f"{row} !== null", 30, "the job's row")
listed = page.js(f"{row}.querySelector('td.id').textContent")
check("the job is listed", listed == job, listed)
page.wait(f"{row}.dataset.status === 'SUCCEEDED' && {row}.querySelector('img.result') "
          f"&& {row}.querySelector('img.result').complete", 120, "the job's image")
status = page.js(f"{row}.querySelector('.status').textContent")
check("status SUCCEEDED", status == "SUCCEEDED", status)
size = page.js(f"(i => [i.naturalWidth, i.naturalHeight])({row}.querySelector('img.result'))")
check("image loaded at 64x48", size == [64, 48], size)
bars = page.js(f"[...{row}.querySelectorAll('.bar')].map(b => [b.querySelector('label')"
               ".textContent, b.querySelector('progress').value, b.querySelector('progress').max])")
check("one full progress bar per stage, plan first",
      len(bars) >= 5 and bars[0][0] == "plan" and all(v == m for _, v, m in bars), bars)
links = page.js(f"[...{row}.querySelectorAll('a')].map(a => a.getAttribute('href'))")
check("links to PNG, PFM, EXR and the report (relative)", links == [
    f"renders/{job}/image", f"renders/{job}/image?format=pfm",
    f"renders/{job}/image?format=exr", f"renders/{job}/report"], links)

# A hostile scene name shows as text.
hostile = "<img src=x onerror=alert(1)>.obj"
tri = "v 0 0 0\\nv 1 0 0\\nv 0 1 0\\nf 1 2 3\\n"
code = page.js(f"""fetch('renders', {{method: 'POST', headers: {{'Content-Type': 'application/json'}},
  body: JSON.stringify({{scene: {{main: {json.dumps(hostile)}, files: {{{json.dumps(hostile)}: "{tri}"}}}},
  width: 8, height: 8}})}}).then(r => r.status)""")
check("the hostile-named job is accepted", code == 202, code)
page.wait(f"[...document.querySelectorAll('#jobs td.scene')].some(td => td.textContent === "
          f"{json.dumps(hostile)})", 30, "the hostile-named job's row")
check("its name shows as text, no element made of it",
      page.js("document.querySelectorAll('#jobs img:not(.result)').length") == 0)
page.wait("!document.querySelector('#jobs tr[data-live]')", 60, "every job to end")
time.sleep(0.5)

shot = page.call("Page.captureScreenshot", format="png")
with open(screenshot, "wb") as f:
    f.write(base64.b64decode(shot["data"]))
print(f"browser: screenshot {screenshot}", flush=True)
page.ws.close()

passed = sum(results)
print(f"{passed} passed, {len(results) - passed} failed", flush=True)
sys.exit(0 if passed == len(results) else 1)
