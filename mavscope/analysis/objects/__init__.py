"""Objects moved over the link, rebuilt from the frames that carried them: files read and written over
MAVLink FTP (and directory listings), logs downloaded with LOG_REQUEST_DATA/LOG_DATA, and images sent as
DATA_TRANSMISSION_HANDSHAKE/ENCAPSULATED_DATA.

`tracker.py` runs the trackers in one pass (`ftp.py`, `logs.py`, `images.py`) over a shared `Context`
(limits, memory budget, transfers in progress); `content.py` holds an object's bytes as they arrive;
`model.py` is what it reports (`ObjectRecord`, `FtpOperation`); `names.py` makes safe file names;
`export.py` the JSON (the manifest); `imageformat.py` says how an image reads and makes its PNG (`png.py`).
"""

from mavscope.analysis.objects.export import manifest_entry, objects_json
from mavscope.analysis.objects.model import (
    DOWNLOAD,
    FTP_LIST,
    FTP_READ,
    FTP_WRITE,
    IMAGE,
    KINDS,
    LOG,
    UPLOAD,
    FtpOperation,
    Limits,
    ObjectRecord,
    party,
)
from mavscope.analysis.objects.names import file_name, flatten, is_plain_name, unsafe_reasons
from mavscope.analysis.objects.tracker import (
    SCRIPT_PATHS,
    TRACKED_MESSAGES,
    ObjectLog,
    ObjectTracker,
    analyse,
    object_findings,
)

__all__ = [
    "DOWNLOAD", "FTP_LIST", "FTP_READ", "FTP_WRITE", "IMAGE", "KINDS", "LOG", "SCRIPT_PATHS", "TRACKED_MESSAGES",
    "UPLOAD", "FtpOperation", "Limits", "ObjectLog", "ObjectRecord", "ObjectTracker", "analyse", "file_name",
    "flatten", "is_plain_name", "manifest_entry", "object_findings", "objects_json", "party", "unsafe_reasons",
]
