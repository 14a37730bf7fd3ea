"""The port moto's Step Functions engine calls for every AWS API (MOTO_PORT; boto_client.py:20
sets endpoint_url=http://localhost:$MOTO_PORT in server mode). Lambda Invoke requests
(POST /2015-03-31/functions/{name or ARN}/invocations) go to `cargo lambda watch`'s Invoke API,
with an ARN cut to its function name; every other request goes to moto unchanged.

    python lambda_proxy.py LISTEN_PORT MOTO_PORT LAMBDA_PORT
"""
import http.client, re, sys, urllib.parse
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

listen, moto, lam = (int(a) for a in sys.argv[1:4])
INVOKE = re.compile(r"^/2015-03-31/functions/([^/]+)/invocations(\?.*)?$")
HOP = {"connection", "keep-alive", "transfer-encoding", "host", "content-length"}


class Proxy(BaseHTTPRequestHandler):
    protocol_version = "HTTP/1.1"

    def log_message(self, fmt, *args):
        if INVOKE.match(self.path):
            sys.stderr.write("lambda-proxy: %s\n" % (fmt % args))

    def _forward(self):
        body = self.rfile.read(int(self.headers.get("Content-Length") or 0))
        path, port = self.path, moto
        m = INVOKE.match(self.path)
        if m and self.command == "POST":
            name = urllib.parse.unquote(m.group(1)).split(":")
            # arn:aws:lambda:REGION:ACCOUNT:function:NAME[:QUALIFIER] -> NAME
            name = name[6] if len(name) >= 7 and name[0] == "arn" else name[-1]
            path, port = f"/2015-03-31/functions/{name}/invocations", lam
        conn = http.client.HTTPConnection("127.0.0.1", port, timeout=3600)
        headers = {k: v for k, v in self.headers.items() if k.lower() not in HOP}
        conn.request(self.command, path, body=body, headers=headers)
        r = conn.getresponse()
        data = r.read()
        status, extra = r.status, {}
        if port == lam and status == 500:
            # `cargo lambda watch` answers a function error with HTTP 500 and the error document;
            # AWS answers 200 with X-Amz-Function-Error (what moto's engine, like the repo's
            # functions/src/aws/invoke.rs, reads as a function error). Without this, botocore
            # raises a ClientError and moto's engine fails on its missing RequestId.
            try:
                import json
                if "errorType" in json.loads(data):
                    status, extra = 200, {"X-Amz-Function-Error": "Unhandled"}
            except ValueError:
                pass
        self.send_response(status)
        for k, v in extra.items():
            self.send_header(k, v)
        for k, v in r.getheaders():
            if k.lower() not in HOP:
                self.send_header(k, v)
        if self.command == "HEAD":
            self.send_header("Content-Length", r.getheader("Content-Length", "0"))
        else:
            self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        self.wfile.write(data)
        conn.close()

    do_GET = do_POST = do_PUT = do_DELETE = do_HEAD = do_PATCH = _forward


ThreadingHTTPServer.daemon_threads = True
ThreadingHTTPServer(("127.0.0.1", listen), Proxy).serve_forever()
