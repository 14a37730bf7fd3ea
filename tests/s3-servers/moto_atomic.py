"""moto_server with S3's conditional PUT made atomic, as it is on AWS.

moto 5.x checks `If-None-Match` / `If-Match` and then writes the object with no lock between the
two (moto/s3/responses.py, `S3Response.put_object`), and its server is threaded, so two racing
conditional PUTs of one key can both succeed where S3 lets exactly one. The store conformance
suite checks that property (`put_if_absent_race_has_one_winner`) and failed on it once on a
loaded machine. This launcher serialises moto's object PUTs so moto has the property too;
everything else is `moto_server` as it is, with the same arguments.
"""

import sys
import threading

from moto.s3.responses import S3Response

_lock = threading.Lock()
_put_object = S3Response.put_object


def put_object(self, *args, **kwargs):
    with _lock:
        return _put_object(self, *args, **kwargs)


S3Response.put_object = put_object

from moto.server import main  # noqa: E402  (after the patch, as moto_server would import it)

sys.exit(main())
