#!/usr/bin/env python3
"""Runs the tutorial book/src/tutorial/your-robot.md as a reader would.

The page is the script: nothing here repeats a command of it. In page order:

* a fenced block preceded by ``<!-- tutorial: file NAME -->`` is written to
  NAME (in the shell's current directory), as the reader saves it;
* every ```console block is run: each ``$ `` line is a command (a trailing
  backslash continues it on the next line), the lines after it up to the next
  ``$ `` are the output the page shows. Every shown line must appear in the
  command's output (stdout and stderr together), in that order, other lines
  may come between them; numbers in a shown line match any number (the page
  shows one run, a run prints its own), ``...`` matches any text, and a line
  of only ``...`` stands for lines left out;
* ``<!-- tutorial: exit N -->`` before a block: its first command must exit
  with N (a command exiting other than 0 fails the run otherwise);
* ``<!-- tutorial: check /REGEX/ OP NUMBER -->`` after a block: REGEX's first
  group, searched in the output of the block's last command, must satisfy OP
  (<, <=, >, >=) NUMBER: the bounds the page states in words;
* ``<!-- tutorial: timeout S -->`` before a block: its commands' ceiling
  (default 90 s each; the longest takes 16 s), and the whole run stops after
  400 s (it takes about 55 s);
* a command ending in `` &`` runs in the background; its stdout must go to a
  file (``> FILE``), which the runner waits for (its first line, 15 s at most)
  before the next command, as the reader waits for the line to appear. It is
  stopped at the end, and a background command that exits early fails the
  run.

Each command runs in bash with the environment and directory the previous
ones left (``export``, ``cd`` carry over, as in one terminal). HOME is a fresh
temporary directory (the page works in ~/my-robot); the run starts in the
repository's root, where the reader built the tools. The build itself (the
page's ```sh block) is not run: CI's test step built target/release/wmr and
hil-sim and the ROS 2 step target/release/wmr-ros2; the runner checks they
exist. Other ```sh blocks are what needs what CI lacks (a ROS 2 install,
Foxglove); they are listed, not run.

The whole run is in a private network namespace (loopback only) because the
ROS 2 bridge starts a DDS participant. Fails loudly with the step (section
and line), the command and what differed; never hangs (a timeout per command,
the background processes killed at the end).

Usage: python3 book/tutorial/run.py [--show] [PAGE]   (--show: print every
command's output, to write the page from)
       python3 book/tutorial/run.py --self-test        (the matching rules)
"""

import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
PAGE = os.path.join(ROOT, "book", "src", "tutorial", "your-robot.md")
BINARIES = ["wmr", "hil-sim", "wmr-ros2"]
DEFAULT_TIMEOUT_S = 90.0
TOTAL_TIMEOUT_S = 400.0
BACKGROUND_READY_S = 15.0
DIRECTIVE = re.compile(r"<!--\s*tutorial:\s*(.*?)\s*-->")
NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


class Failure(Exception):
    """The run failed: the message says where and what."""


class Command:
    def __init__(self, text, line, section, expected, exit_code, timeout_s):
        self.text = text
        self.line = line
        self.section = section
        self.expected = expected
        self.exit_code = exit_code
        self.timeout_s = timeout_s
        self.checks = []

    def where(self):
        return f"line {self.line} (section \"{self.section}\")"


class File:
    def __init__(self, name, content, line):
        self.name = name
        self.content = content
        self.line = line


def parse(path):
    """The page's steps in order: File and Command objects, and the ```sh
    blocks not run."""
    return parse_text(open(path, encoding="utf-8").read(), path)


def parse_text(text, path):
    """parse() of the page's text."""
    lines = text.split("\n")
    steps, skipped = [], []
    section = "(top)"
    pending = {}
    i = 0
    while i < len(lines):
        line = lines[i]
        if line.startswith("#") and not pending.get("in_block"):
            section = line.lstrip("#").strip()
        m = DIRECTIVE.search(line)
        if m:
            words = m.group(1).split(None, 1)
            kind = words[0] if words else ""
            arg = words[1] if len(words) > 1 else ""
            if kind == "file":
                pending["file"] = arg
            elif kind == "exit":
                pending["exit"] = int(arg)
            elif kind == "timeout":
                pending["timeout"] = float(arg)
            elif kind == "check":
                cm = re.fullmatch(r"/(.*)/\s*(<=|>=|<|>)\s*(" + NUMBER + r")", arg)
                if not cm:
                    raise Failure(f"{path}:{i + 1}: bad check directive: {line.strip()}")
                last = next((s for s in reversed(steps) if isinstance(s, Command)), None)
                if last is None:
                    raise Failure(f"{path}:{i + 1}: a check before any command")
                last.checks.append((cm.group(1), cm.group(2), float(cm.group(3)), i + 1))
            else:
                raise Failure(f"{path}:{i + 1}: unknown directive: {line.strip()}")
            i += 1
            continue
        fence = re.match(r"^(```+)\s*(\S*)", line)
        if fence:
            ticks, info = fence.group(1), fence.group(2)
            start = i + 1
            j = start
            while j < len(lines) and not lines[j].startswith(ticks):
                j += 1
            if j == len(lines):
                raise Failure(f"{path}:{i + 1}: a code block that never ends")
            body = lines[start:j]
            if "file" in pending:
                steps.append(File(pending.pop("file"), "\n".join(body) + "\n", i + 1))
            elif info == "console":
                steps.extend(parse_console(body, start + 1, section, pending))
            elif info == "sh":
                skipped.append((i + 1, section, body[0] if body else ""))
            pending = {}
            i = j + 1
            continue
        i += 1
    return steps, skipped


def parse_console(body, first_line, section, pending):
    """The commands of one console block with their shown output."""
    commands = []
    k = 0
    while k < len(body):
        if not body[k].startswith("$ "):
            if body[k].strip():
                raise Failure(
                    f"line {first_line + k}: output before any command in a console block: {body[k]!r}"
                )
            k += 1
            continue
        line_no = first_line + k
        text = body[k][2:]
        while text.endswith("\\") and k + 1 < len(body):
            k += 1
            text = text[:-1] + "\n" + body[k]
        k += 1
        expected = []
        while k < len(body) and not body[k].startswith("$ "):
            if body[k].strip():
                expected.append(body[k])
            k += 1
        exit_code = pending.pop("exit", 0) if not commands else 0
        commands.append(
            Command(text, line_no, section, expected, exit_code,
                    pending.get("timeout", DEFAULT_TIMEOUT_S))
        )
    return commands


def pattern(shown):
    """A shown output line as a regex over an output line (whitespace
    collapsed): numbers match any number, `...` any text."""
    parts = re.split(r"(\.\.\.|…|" + NUMBER + r")", " ".join(shown.split()))
    out = []
    for p in parts:
        if p in ("...", "…"):
            out.append(".*?")
        elif re.fullmatch(NUMBER, p or "x"):
            out.append(NUMBER)
        else:
            out.append(re.escape(p))
    return re.compile("^" + "".join(out) + "$")


def compare(cmd, output):
    """Every shown line found in order; raises Failure naming the first
    missing one."""
    actual = [" ".join(l.split()) for l in output.split("\n")]
    pos = 0
    for shown in cmd.expected:
        if shown.strip() in ("...", "…"):
            continue
        rx = pattern(shown)
        found = next((n for n in range(pos, len(actual)) if rx.match(actual[n])), None)
        if found is None:
            earlier = next((n for n in range(0, pos) if rx.match(actual[n])), None)
            hint = (f" (it came earlier, at output line {earlier + 1}: the order differs)"
                    if earlier is not None else "")
            raise Failure(
                f"{cmd.where()}: `{cmd.text}`: the page shows the line\n    {shown.strip()}\n"
                f"but the output has no such line after output line {pos}{hint}.\n"
                f"--- output:\n{output}"
            )
        pos = found + 1


def check_bounds(cmd, output):
    for regex, op, bound, line in cmd.checks:
        m = re.search(regex, output)
        if not m:
            raise Failure(f"line {line}: check /{regex}/ found nothing in the output of "
                          f"`{cmd.text}` ({cmd.where()})\n--- output:\n{output}")
        value = float(m.group(1))
        ok = {"<": value < bound, "<=": value <= bound,
              ">": value > bound, ">=": value >= bound}[op]
        if not ok:
            raise Failure(f"line {line}: `{cmd.text}` ({cmd.where()}): {m.group(0)!r} gives "
                          f"{value}, the page says {op} {bound}")
        print(f"    check: {value:g} {op} {bound:g}  ok")


class Shell:
    """The reader's terminal: environment and directory carried from one
    command to the next; background jobs kept to be stopped at the end."""

    def __init__(self, home):
        self.env = dict(os.environ)
        self.env["HOME"] = home
        self.cwd = ROOT
        self.state = tempfile.mkdtemp(prefix="tutorial-shell-")
        self.jobs = []

    def script(self, text):
        st = self.state
        return (f"{text}\n__rc=$?\npwd > {st}/cwd\nenv -0 > {st}/env\nexit $__rc\n")

    def carry(self):
        with open(f"{self.state}/cwd") as f:
            self.cwd = f.read().strip()
        with open(f"{self.state}/env", "rb") as f:
            raw = f.read().decode(errors="replace")
        self.env = dict(kv.split("=", 1) for kv in raw.split("\0") if "=" in kv)

    def run(self, cmd, timeout_s):
        proc = subprocess.Popen(
            ["bash", "-c", self.script(cmd.text)], cwd=self.cwd, env=self.env,
            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
            start_new_session=True,
        )
        try:
            out, _ = proc.communicate(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            kill_group(proc)
            out, _ = proc.communicate()
            raise Failure(f"{cmd.where()}: `{cmd.text}` did not end within {timeout_s:.0f} s "
                          f"(killed)\n--- output so far:\n{out.decode(errors='replace')}")
        self.carry()
        return proc.returncode, out.decode(errors="replace")

    def background(self, cmd):
        text = cmd.text.rstrip()[:-1].rstrip()
        m = re.search(r"(?<![0-9&])>\s*(\S+)", text)
        if not m:
            raise Failure(f"{cmd.where()}: `{cmd.text}`: a background command must send its "
                          f"output to a file (> FILE) for the next command to read")
        name = m.group(1)
        if name.startswith("~/"):
            name = os.path.join(self.env["HOME"], name[2:])
        out_file = os.path.join(self.cwd, name)
        if os.path.exists(out_file):
            os.unlink(out_file)
        proc = subprocess.Popen(["bash", "-c", "exec " + text], cwd=self.cwd, env=self.env,
                                stdin=subprocess.DEVNULL, start_new_session=True)
        self.jobs.append((cmd, proc))
        t_end = time.monotonic() + BACKGROUND_READY_S
        while True:
            if os.path.exists(out_file) and open(out_file, "rb").read().find(b"\n") >= 0:
                return
            if proc.poll() is not None:
                raise Failure(f"{cmd.where()}: `{cmd.text}` exited with status {proc.returncode} "
                              f"before printing its first line to {m.group(1)}")
            if time.monotonic() > t_end:
                raise Failure(f"{cmd.where()}: `{cmd.text}` printed nothing to {m.group(1)} "
                              f"within {BACKGROUND_READY_S:g} s")
            time.sleep(0.05)

    def check_jobs(self):
        for cmd, proc in self.jobs:
            if proc.poll() is not None:
                raise Failure(f"the background command of {cmd.where()}, `{cmd.text}`, "
                              f"exited early with status {proc.returncode}")

    def stop(self):
        for _, proc in self.jobs:
            kill_group(proc)


def kill_group(proc):
    """SIGTERM to the process group, SIGKILL after 5 s."""
    if proc.poll() is not None:
        return
    try:
        os.killpg(proc.pid, signal.SIGTERM)
    except ProcessLookupError:
        return
    try:
        proc.wait(timeout=5)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()


def in_private_network():
    """Re-runs this script in a private network namespace (loopback with
    multicast, as wmr-ros2/check/run.sh) unless already in one."""
    if os.environ.get("TUTORIAL_IN_NETNS"):
        return
    setup = ("ip link set lo up && ip link set lo multicast on && "
             "ip route add 224.0.0.0/4 dev lo && exec env TUTORIAL_IN_NETNS=1 "
             + " ".join(shlex.quote(a) for a in [sys.executable] + sys.argv))
    os.execvp("unshare", ["unshare", "-n", "bash", "-c", setup])


def self_test():
    """The matching rules on made-up output: each case could fail for a
    real bug in pattern() or compare()."""
    def ok(shown, output):
        try:
            compare(Command("cmd", 1, "s", shown, 0, 1.0), output)
            return True
        except Failure:
            return False
    out = "a 1.5 m\nnoise\nb -3e-4 rad (x 12)\nc done"
    cases = [
        (["a 2.25 m", "b 7 rad (x 1)"], True),      # numbers vary, lines between
        (["a 2.25 m", "c done"], True),
        (["b 7 rad (x 1)", "a 2.25 m"], False),     # order
        (["a 2.25 km"], False),                     # a unit is text
        (["a m"], False),                           # a number left out
        (["b ... (x 1)"], True),                    # ... is any text
        (["...", "c done"], True),                  # a line of ... skips
        (["c   done"], True),                       # whitespace collapsed
        (["c done!"], False),
        (["d"], False),
    ]
    for shown, want in cases:
        if ok(shown, out) != want:
            print(f"tutorial: self-test FAIL: {shown} against {out!r}: expected "
                  f"{'a match' if want else 'no match'}", file=sys.stderr)
            return 1
    steps, _ = parse_text("<!-- tutorial: exit 1 -->\n```console\n$ false \\\n  x\nshown\n$ true\n```\n"
                          "<!-- tutorial: check /v=([0-9.]+)/ < 2 -->\n", "self-test")
    if ([(c.text, c.exit_code, c.expected, len(c.checks)) for c in steps]
            != [("false \n  x", 1, ["shown"], 0), ("true", 0, [], 1)]):
        print(f"tutorial: self-test FAIL: parse gave {[(c.text, c.exit_code, c.expected) for c in steps]}",
              file=sys.stderr)
        return 1
    print(f"tutorial: runner self-test passed ({len(cases) + 1} cases)")
    return 0


def main():
    args = sys.argv[1:]
    if "--self-test" in args:
        return self_test()
    show = "--show" in args
    args = [a for a in args if a != "--show"]
    page = os.path.abspath(args[0]) if args else PAGE
    missing = [b for b in BINARIES if not os.access(os.path.join(ROOT, "target", "release", b), os.X_OK)]
    if missing:
        print(f"tutorial: FAIL: target/release/{', '.join(missing)} missing: build them as the page "
              f"says (cargo build --release -p wmr -p hil-sim; cd wmr-ros2 && cargo build --release --locked)",
              file=sys.stderr)
        return 1
    in_private_network()
    try:
        steps, skipped = parse(page)
    except Failure as e:
        print(f"tutorial: FAIL: {e}", file=sys.stderr)
        return 1
    n_cmd = sum(isinstance(s, Command) for s in steps)
    if n_cmd == 0:
        print(f"tutorial: FAIL: {page} has no ```console command", file=sys.stderr)
        return 1
    rel = os.path.relpath(page, ROOT)
    print(f"tutorial: {rel}: {n_cmd} commands, {sum(isinstance(s, File) for s in steps)} files, "
          f"{len(skipped)} ```sh blocks not run")
    for line, section, first in skipped:
        print(f"  not run (needs what CI lacks), line {line} in \"{section}\": {first}")
    home = tempfile.mkdtemp(prefix="tutorial-home-")
    shell = Shell(home)
    t0 = time.monotonic()
    try:
        for n, step in enumerate(steps, 1):
            if isinstance(step, File):
                path = os.path.join(shell.cwd, step.name)
                with open(path, "w", encoding="utf-8") as f:
                    f.write(step.content)
                print(f"[{time.monotonic() - t0:5.1f} s] step {n}: wrote {step.name} (line {step.line})")
                continue
            shell.check_jobs()
            print(f"[{time.monotonic() - t0:5.1f} s] step {n}: line {step.line}: $ {step.text}")
            if step.text.rstrip().endswith("&") and not step.text.rstrip().endswith("&&"):
                shell.background(step)
                continue
            left_s = TOTAL_TIMEOUT_S - (time.monotonic() - t0)
            if left_s <= 0:
                raise Failure(f"{step.where()}: the run took more than {TOTAL_TIMEOUT_S:g} s before "
                              f"reaching `{step.text}`")
            rc, out = shell.run(step, min(step.timeout_s, left_s))
            if show:
                print(out.rstrip("\n"))
            if rc != step.exit_code:
                raise Failure(f"{step.where()}: `{step.text}` exited with status {rc}, the page "
                              f"expects {step.exit_code}\n--- output:\n{out}")
            compare(step, out)
            check_bounds(step, out)
        shell.check_jobs()
    except Failure as e:
        print(f"tutorial: FAIL: {rel} {e}", file=sys.stderr)
        print(f"(the reader's home for this run: {home})", file=sys.stderr)
        return 1
    finally:
        shell.stop()
        shutil.rmtree(shell.state, ignore_errors=True)
    print(f"tutorial: all {n_cmd} commands of {rel} passed in {time.monotonic() - t0:.1f} s")
    shutil.rmtree(home, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
