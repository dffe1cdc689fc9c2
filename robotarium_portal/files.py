"""The experiments' files on disk: names that stay inside the experiment's folder, and the downloads."""
import mimetypes
import os
import re
import shutil

from django.http import FileResponse, Http404, HttpResponse

# Letters, digits, '.', '-', '_'; not starting with a dot (no '..', no hidden files); at most 100 characters.
SAFE_NAME = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9._-]{0,99}")
NAME_RULE = "use letters, digits, '.', '-' and '_' only, not starting with a dot, at most 100 characters"


def name_problem(name):
    """Why `name` may not be an experiment's file name, or None when it may."""
    if not SAFE_NAME.fullmatch(name or ""):
        return "the file name %r is not allowed: %s" % (name, NAME_RULE)
    return None


def inside(folder, name):
    """folder/name, refused (Http404) when it would lie anywhere but directly in folder."""
    if name_problem(name) and not _is_results_path(name):
        raise Http404("no such file")
    folder = os.path.realpath(folder)
    path = os.path.realpath(os.path.join(folder, name))
    if os.path.dirname(path) != folder and not path.startswith(folder + os.sep):
        raise Http404("no such file")
    return path


def result_path(folder, name):
    """folder/name for a file of a run's results: `name` one of the plain files the folder lists, or
    data/<one the data/ folder lists> (whatever its characters: a script names its own files). Http404
    for anything else, so no name leaves the folder."""
    parts = name.split("/")
    where = folder if len(parts) == 1 else os.path.join(folder, "data") if len(parts) == 2 and parts[0] == "data" else None
    try:
        entries = os.listdir(where) if where else []
    except OSError:
        entries = []
    if parts[-1] not in entries or not os.path.isfile(os.path.join(where, parts[-1])):
        raise Http404("no such file")
    return os.path.join(where, parts[-1])


def _is_results_path(name):
    """data/<file>: the run folder's saved data files are one level down."""
    parts = name.split("/")
    return len(parts) == 2 and parts[0] == "data" and not name_problem(parts[1])


def save_upload(folder, upload):
    path = inside(folder, upload.name)
    os.makedirs(folder, exist_ok=True)
    with open(path, "wb") as f:
        for chunk in upload.chunks():
            f.write(chunk)


def copy_files(source, target):
    """The uploaded files into a fresh working folder (each job works on its own copy)."""
    os.makedirs(target, exist_ok=True)
    for name in os.listdir(source):
        shutil.copy2(os.path.join(source, name), os.path.join(target, name))


def listing(folder, sub=""):
    """[(relative name, size)] of the plain files directly in folder/sub."""
    where = os.path.join(folder, sub) if sub else folder
    if not folder or not os.path.isdir(where):
        return []
    return [((sub + "/" + n) if sub else n, os.path.getsize(os.path.join(where, n)))
            for n in sorted(os.listdir(where)) if os.path.isfile(os.path.join(where, n))]


_RANGE = re.compile(r"bytes=(\d*)-(\d*)$")


def download(request, path, as_attachment=False):
    """The file, with HTTP Range answered (a browser's <video> seeks with it)."""
    if not os.path.isfile(path):
        raise Http404("no such file")
    size = os.path.getsize(path)
    content_type = content_type_of(path)
    match = _RANGE.match(request.headers.get("Range", ""))
    if match and (match.group(1) or match.group(2)):
        first, last = match.groups()
        if first:
            start, end = int(first), min(int(last) if last else size - 1, size - 1)
        else:
            start, end = max(0, size - int(last)), size - 1
        if start > end or start >= size:
            response = HttpResponse(status=416)
            response["Content-Range"] = "bytes */%d" % size
            return response
        with open(path, "rb") as f:
            f.seek(start)
            body = f.read(end - start + 1)
        response = HttpResponse(body, status=206, content_type=content_type)
        response["Content-Range"] = "bytes %d-%d/%d" % (start, end, size)
        response["Accept-Ranges"] = "bytes"
        return response
    response = FileResponse(open(path, "rb"), as_attachment=as_attachment, filename=os.path.basename(path),
                            content_type=content_type)
    response["Accept-Ranges"] = "bytes"
    return response


# Served as text: what a browser would otherwise run as a page of this site (a user's .html or .svg).
ACTIVE_TYPES = {"text/html", "image/svg+xml", "application/javascript", "text/javascript", "application/xhtml+xml",
                "text/xml", "application/xml"}


def content_type_of(path):
    guessed = mimetypes.guess_type(path)[0]
    if guessed is None or guessed in ACTIVE_TYPES or guessed.startswith("text/") or path.endswith(".py"):
        return "text/plain; charset=utf-8"
    return guessed
