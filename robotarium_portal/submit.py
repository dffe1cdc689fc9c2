"""./robotarium submit: an experiment to a Robotarium portal from the terminal, followed to its end.

It sends the files through the portal's JSON API with the person's API token (--token or
ROBOTARIUM_TOKEN), prints each state as it changes (the place in the queue, the step while it runs),
and, once it completed, downloads its results folder (report, video, log, data files, recording) into
the current folder or --out DIR, printing its path last. Exit codes as verify's: 0 completed,
6 rejected (the rules printed), 4 failed or cancelled, 2 a bad command line or a refusal, 1 the portal
unreachable. Plain Python (urllib), nothing of Django: it runs wherever the repository is.
"""
import argparse
import json
import mimetypes
import os
import secrets
import sys
import time
import urllib.error
import urllib.parse
import urllib.request

COMPLETED, REJECTED, FAILED, USAGE, UNREACHABLE = 0, 6, 4, 2, 1
FINISHED = {"completed": COMPLETED, "rejected": REJECTED, "failed": FAILED, "cancelled": FAILED}
POLL = 0.5   # s between two looks at the experiment's state


class Refused(Exception):
    """The portal answered with an error the person can act on (its message says what)."""


def parse(argv):
    parser = argparse.ArgumentParser(
        prog="./robotarium submit",
        description="Submit an experiment to a Robotarium portal (./robotarium serve), follow it through its "
                    "verification, the queue and its run, and download its results when it completes.",
        epilog="The token: make one on the portal's account page (or an operator: ./robotarium serve --data DIR "
               "--create-token EMAIL). Exit codes: 0 completed, 6 rejected by the verification (the rules are "
               "printed), 4 failed or cancelled, 2 refused (a bad file, the account may not submit yet), 1 the "
               "portal did not answer.")
    parser.add_argument("main", metavar="MAIN.py", help="the script that is run")
    parser.add_argument("files", nargs="*", metavar="FILES", help="the modules it imports, the data files it reads")
    parser.add_argument("--robots", type=int, required=True, metavar="N", help="how many robots the script asks for")
    parser.add_argument("--duration", type=int, required=True, metavar="S",
                        help="its estimated duration in seconds (1 to 900); the verification allows 1.5 x")
    parser.add_argument("--title", help="its title (default: the main file's name)")
    parser.add_argument("--description", default="", help="its description")
    parser.add_argument("--portal", required=True, metavar="URL", help="the portal's address, e.g. http://lab:8000/")
    parser.add_argument("--token", default=os.environ.get("ROBOTARIUM_TOKEN", ""),
                        help="your API token (default: $ROBOTARIUM_TOKEN)")
    parser.add_argument("--out", default=".", metavar="DIR", help="where the results folder goes (default: here)")
    args = parser.parse_args(argv)
    if not args.token:
        parser.error("no API token: give --token or set ROBOTARIUM_TOKEN (make one on the portal's account page)")
    for path in [args.main, *args.files]:
        if not os.path.isfile(path):
            parser.error("no such file: %s" % path)
    return args


class Portal:
    def __init__(self, url, token):
        self.base = url.rstrip("/") + "/"
        self.token = token

    def request(self, path, body=None, content_type=None):
        headers = {"Authorization": "Bearer " + self.token, "Accept": "application/json"}
        if content_type:
            headers["Content-Type"] = content_type
        request = urllib.request.Request(urllib.parse.urljoin(self.base, path.lstrip("/")), data=body,
                                         headers=headers)
        try:
            return urllib.request.urlopen(request, timeout=60)
        except urllib.error.HTTPError as error:
            try:
                answer = json.loads(error.read() or b"{}")
            except ValueError:
                answer = {}
            raise Refused(_explain(error.code, answer)) from None

    def json(self, path, body=None, content_type=None):
        with self.request(path, body, content_type) as response:
            return json.loads(response.read())


def _explain(code, answer):
    if code == 401:
        return "the portal refused the token (%s)" % answer.get("error", "401")
    fields = answer.get("fields") or {}
    if fields:
        return "not submitted: " + "; ".join("%s: %s" % (k, " ".join(v)) for k, v in fields.items())
    return answer.get("error") or "the portal answered %d" % code


def multipart(fields, files):
    """(body, content type) of a multipart/form-data POST."""
    boundary = "robotarium-" + secrets.token_hex(12)
    parts = []
    for name, value in fields.items():
        parts.append(('--%s\r\nContent-Disposition: form-data; name="%s"\r\n\r\n%s\r\n'
                      % (boundary, name, value)).encode())
    for path in files:
        kind = mimetypes.guess_type(path)[0] or "application/octet-stream"
        with open(path, "rb") as f:
            data = f.read()
        parts.append(('--%s\r\nContent-Disposition: form-data; name="upload"; filename="%s"\r\nContent-Type: %s'
                      '\r\n\r\n' % (boundary, os.path.basename(path), kind)).encode() + data + b"\r\n")
    parts.append(("--%s--\r\n" % boundary).encode())
    return b"".join(parts), "multipart/form-data; boundary=" + boundary


def said(experiment):
    """One line on where the experiment is."""
    state, line = experiment["state"], experiment["state"]
    if state == "queued" and experiment.get("place_in_queue"):
        line += " (place %d in the queue)" % experiment["place_in_queue"]
    elif state == "running" and experiment.get("step") is not None:
        line += " (step %d)" % experiment["step"]
    return line


def follow(portal, experiment):
    """Print the states as they change until it is finished; the finished experiment."""
    last = None
    while True:
        line = said(experiment)
        if line != last:
            print("[robotarium] experiment #%d: %s" % (experiment["id"], line), flush=True)
            last = line
        if experiment["state"] in FINISHED:
            return experiment
        time.sleep(POLL)
        experiment = portal.json("api/experiments/%d/" % experiment["id"])


def download(portal, experiment, out):
    """The results folder into out/; its path."""
    folder = os.path.join(out, experiment["results_folder"] or "experiment-%d" % experiment["id"])
    for item in experiment["results"]:
        path = os.path.join(folder, *item["name"].split("/"))
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with portal.request(item["url"]) as response, open(path, "wb") as f:
            while chunk := response.read(1 << 20):
                f.write(chunk)
    return os.path.abspath(folder)


def main(argv=None):
    args = parse(argv)
    portal = Portal(args.portal, args.token)
    fields = {"title": args.title or os.path.basename(args.main), "description": args.description,
              "estimated_duration": args.duration, "number_of_robots": args.robots,
              "main_file": os.path.basename(args.main), "action": "submit"}
    try:
        experiment = portal.json("api/experiments/", *multipart(fields, [args.main, *args.files]))
        print("[robotarium] submitted experiment #%d \"%s\": %s" % (experiment["id"], experiment["title"],
                                                                     urllib.parse.urljoin(portal.base, experiment["page"][1:])),
              flush=True)
        experiment = follow(portal, experiment)
    except Refused as error:
        print("[robotarium] error: %s" % error, file=sys.stderr)
        return USAGE
    except (urllib.error.URLError, OSError) as error:
        print("[robotarium] error: the portal at %s did not answer (%s)" % (portal.base, getattr(error, "reason", error)),
              file=sys.stderr)
        return UNREACHABLE
    except KeyboardInterrupt:
        print("\n[robotarium] stopped following it; the experiment goes on at the portal", file=sys.stderr)
        return 130
    if experiment["state"] == "rejected":
        for rule in experiment["rules"]:
            print("[robotarium] rejected: %s" % _rule_line(rule))
        if not experiment["rules"]:
            print("[robotarium] rejected: %s" % experiment["detail"])
    elif experiment["state"] != "completed":
        print("[robotarium] %s: %s" % (experiment["state"], experiment["detail"]))
    if experiment["state"] == "completed" or experiment["results"]:
        try:
            print(download(portal, experiment, args.out), flush=True)
        except (Refused, urllib.error.URLError, OSError) as error:
            print("[robotarium] error: the results could not be downloaded (%s); they are on the portal" % error,
                  file=sys.stderr)
            return UNREACHABLE
    return FINISHED[experiment["state"]]


def _rule_line(rule):
    count = (" %s times, limit %s" % (rule.get("count"), rule.get("limit"))) if rule.get("limit") is not None else ""
    first = (" (first at step %s)" % rule["first_step"]) if rule.get("first_step") is not None else ""
    return "%s:%s%s %s" % (rule.get("rule"), count, first, rule.get("message") or "")


if __name__ == "__main__":
    sys.exit(main())
