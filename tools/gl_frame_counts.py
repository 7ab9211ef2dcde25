#!/usr/bin/env python3
"""Counts what each frame of a traced run asked of the OpenGL driver, from outside the program.

Usage: gl_frame_counts.py TRACE      (a trace from `apitrace trace --api egl -o TRACE PROGRAM ...`)

Prints a JSON list with one object per KHR_debug group named "frame" (layertrace's resident GPU
frame pushes one per frame), each counting the calls from that group's push to its pop:
program_links, buffer_allocations, upload_bytes, download_bytes, host_waits, dispatches, draws.
A host wait is a blocking call (a buffer or texture read-back, glFinish, glClientWaitSync, a query
result read) after new GPU work (a draw or a dispatch) was submitted: the host stalls there once;
blocking calls before the next submission do not stall again. These are the rules the program's
own accounting (stats key gpu.frame) follows, so the two can be compared call for call.
"""
import json
import re
import subprocess
import sys

CALL = re.compile(r"^\d+ (gl[A-Za-z0-9]+)\((.*)")
READS = {"glGetNamedBufferSubData", "glGetBufferSubData", "glGetTexImage", "glGetTextureImage", "glGetTextureSubImage", "glReadPixels",
         "glReadnPixels", "glFinish", "glClientWaitSync"}
STORAGE = {"glNamedBufferStorage", "glBufferStorage", "glBufferData", "glNamedBufferData", "glTexStorage2D", "glTexStorage3D",
           "glTextureStorage2D", "glTextureStorage3D", "glTexImage2D", "glTexImage3D"}
KEYS = ("program_links", "buffer_allocations", "upload_bytes", "download_bytes", "host_waits", "dispatches", "draws")


def argument(args, name):
    m = re.search(r"\b" + name + r" = (\d+)", args)
    return int(m.group(1)) if m else 0


def main():
    dump = subprocess.run(["apitrace", "dump", "--color=never", sys.argv[1]], capture_output=True, text=True, check=True).stdout
    frames, current, submitted, depth = [], None, False, 0
    for line in dump.splitlines():
        m = CALL.match(line)
        if not m:
            continue
        f, args = m.group(1), m.group(2)
        if f == "glPushDebugGroup" and current is None and 'message = "frame"' in args:
            current = dict.fromkeys(KEYS, 0)
            frames.append(current)
        elif f == "glPushDebugGroup" and current is not None:
            depth += 1
        elif f == "glPopDebugGroup" and current is not None:
            if depth == 0:
                current = None  # the frame's group ends; blocking calls still clear `submitted`
            else:
                depth -= 1
        blocking = f in READS or (f.startswith("glGetQueryObject") and "GL_QUERY_RESULT," in args.replace(" ", "")) or \
            (f.startswith(("glMapBuffer", "glMapNamedBuffer")) and "READ" in args)
        if blocking and submitted:
            submitted = False
            if current is not None:
                current["host_waits"] += 1
        if f.startswith("glDispatchCompute"):
            submitted = True
        elif f.startswith(("glDraw", "glMultiDraw")):
            submitted = True
        if current is None:
            continue
        if f in ("glLinkProgram", "glCreateShaderProgramv"):
            current["program_links"] += 1
        elif f in STORAGE:
            current["buffer_allocations"] += 1
            if "blob(" in args:
                current["upload_bytes"] += argument(args, "size")
        elif f in ("glNamedBufferSubData", "glBufferSubData"):
            current["upload_bytes"] += argument(args, "size")
        elif f in ("glGetNamedBufferSubData", "glGetBufferSubData"):
            current["download_bytes"] += argument(args, "size")
        elif f.startswith("glDispatchCompute"):
            current["dispatches"] += 1
        elif f.startswith(("glDraw", "glMultiDraw")):
            current["draws"] += 1
    json.dump(frames, sys.stdout)
    print()


if __name__ == "__main__":
    main()
