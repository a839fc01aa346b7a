#!/usr/bin/env python3
"""Checks that tests fail when the code they guard is broken on purpose.

Each entry of tests/deliberate_breaks.json names a test, a deliberate break (one text replacement in one source
file, or only environment variables) and how the test fails on it. For each entry this script applies the break,
builds the targets named, runs the test binary on the test, restores the file (also when interrupted) and
reports whether the test failed as it must. Run it from the repository root on a built tree (build/); it
rebuilds the touched targets once more at the end so that build/ matches the checkout again.

    scripts/deliberate_breaks.py [NAME ...]     # all entries, or the named ones

Exit status 0 when every test run failed on its break, 1 otherwise. A test that still passes on its break
checks less than it claims.
"""
import json
import os
import signal
import subprocess
import sys

BREAKS = "tests/deliberate_breaks.json"


def build(targets):
    return subprocess.run(["cmake", "--build", "build", "-j2", "--target"] + targets, capture_output=True, text=True)


def run_entry(entry):
    path = entry.get("file")
    original = None
    if path:
        with open(path, encoding="utf-8") as f:
            original = f.read()
        if original.count(entry["old"]) != 1:
            return False, "the text to replace is not found once in %s (update %s)" % (path, BREAKS)
        with open(path, "w", encoding="utf-8") as f:
            f.write(original.replace(entry["old"], entry["new"]))
    try:
        built = build(entry["targets"])
        if built.returncode != 0:
            return False, "build failed:\n" + built.stdout[-2000:]
        env = dict(os.environ, **entry.get("env", {}))
        command = ["timeout", str(entry.get("timeout", 600)), entry["binary"], "--gtest_filter=" + entry["test"]]
        result = subprocess.run(command, capture_output=True, text=True, env=env)
        failed = result.returncode != 0 and "[  PASSED  ] 1 test" not in result.stdout
        first = next((l for l in result.stdout.splitlines() if "Failure" in l or "FAILED" in l), "")
        how = "exit %d%s" % (result.returncode, " (timed out)" if result.returncode == 124 else "")
        return failed, how + ("; " + first if first else "")
    finally:
        if original is not None:
            with open(path, "w", encoding="utf-8") as f:
                f.write(original)


def main():
    # SIGTERM restores the file as Ctrl-C does (the finally block of run_entry).
    signal.signal(signal.SIGTERM, lambda *_: (_ for _ in ()).throw(KeyboardInterrupt()))
    with open(BREAKS, encoding="utf-8") as f:
        entries = json.load(f)
    names = set(sys.argv[1:])
    unknown = names - {e["name"] for e in entries}
    if unknown:
        print("deliberate_breaks.py: unknown names: %s" % ", ".join(sorted(unknown)), file=sys.stderr)
        return 2
    ok = True
    touched = set()
    for k, entry in enumerate(e for e in entries if not names or e["name"] in names):
        failed, how = run_entry(entry)
        touched.update(entry["targets"])
        ok = ok and failed
        print("%-26s %s: %s (%s)" % (entry["name"], "fails as it must" if failed else "STILL PASSES", entry["test"],
                                     how), flush=True)
        if not failed:
            print("    expected: " + entry["fails"], flush=True)
    if touched:
        build(sorted(touched))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
