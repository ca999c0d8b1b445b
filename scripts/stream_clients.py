"""The clients of scripts/stream_load.py (see its header): a paced sender of frames, the soak's
behaviours (normal, cut mid-frame at the socket level, garbage, stalled), the soak's last
phase (the session limit's 1013 and the shutdown's 1001) and the checked session that
docker/smoke.sh runs through the balancer.

Uses `websockets` (asyncio API) with keep-alive pings off: a client's ping is a message to
the server and would keep a stalled session from its idle timeout. The cut clients speak
RFC 6455 on a raw socket, so that they can stop in the middle of a frame.
"""

import asyncio
import base64
import json
import os
import random
import socket
import struct
import time
import urllib.parse

from websockets.asyncio.client import connect as ws_connect
from websockets.exceptions import ConnectionClosed

DOCUMENTED = {1000, 1001, 1008, 1013}
WAIT_S = 60  # longest wait for one answer


def connect(url, **kw):
    """A client connection: no message size limit, no keep-alive pings, no compression."""
    return ws_connect(url, max_size=None, ping_interval=None, compression=None,
                      open_timeout=20, close_timeout=10, **kw)


def frame_at(frames, k):
    """Frame k of the video played back and forth (continuous motion)."""
    n = len(frames)
    cycle = max(1, 2 * n - 2)
    i = k % cycle
    return frames[i if i < n else cycle - i]


def counters():
    """A session's counts, filled by `pump`."""
    return {"sent": 0, "late": 0, "dropped": 0, "problems": 0, "problem_codes": {},
            "markers": 0, "latencies_ms": [], "errors": []}


def note_problem(r, answer):
    """Counts a problem answer by its code."""
    r["problems"] += 1
    code = answer.get("code", "?")
    r["problem_codes"][code] = r["problem_codes"].get(code, 0) + 1


async def pump(ws, frames, fps, start_at, end_at, offset, r):
    """Sends frames at `fps` paced by the clock from `start_at` until `end_at` (monotonic s),
    each after its meta (`frame_id`, `capture_time_ms` on the wall clock), while reading the
    answers: checks their order, counts drops, problems and latencies (send to answer)."""
    sent, state = {}, {"finished": False, "last": -1}
    done = asyncio.Event()

    async def receive():
        try:
            await receive_all()
        except ConnectionClosed:
            done.set()  # the sender's next send raises it to the caller

    async def receive_all():
        async for message in ws:
            t = time.monotonic()
            answer = json.loads(message)
            fr = answer["frame"]
            fid = fr["id"]
            # A numeric id comes back as a JSON float (17 as 17.0): compare numbers.
            if not isinstance(fid, (int, float)) or fid <= state["last"]:
                r["errors"].append(f"answer out of order: {fr} after id {state['last']}")
            state["last"] = fid
            r["dropped"] += fr["dropped_before"]
            t_sent = sent.pop(fid, None)
            for k in [k for k in sent if k < fid]:
                del sent[k]  # dropped by the server
            if t_sent is not None:
                r["latencies_ms"].append((t - t_sent) * 1e3)
            if "markers" in answer:
                r["markers"] += len(answer["markers"])
            else:
                note_problem(r, answer)
            if state["finished"] and not sent:
                done.set()

    receiver = asyncio.create_task(receive())
    period = 1 / fps
    now = time.monotonic()
    epoch0_ms = time.time() * 1e3 + (start_at - now) * 1e3
    if start_at > now:
        await asyncio.sleep(start_at - now)
    k = 0
    while True:
        t_sched = start_at + k * period
        if t_sched >= end_at:
            break
        now = time.monotonic()
        if now < t_sched:
            await asyncio.sleep(t_sched - now)
        elif now - t_sched > period:  # behind: skip what a camera would have skipped
            skipped = int((now - t_sched) / period)
            r["late"] += skipped
            k += skipped
            continue
        meta = {"frame_id": k, "capture_time_ms": round(epoch0_ms + k * period * 1e3, 3)}
        sent[k] = time.monotonic()
        await ws.send(json.dumps(meta))
        await ws.send(frame_at(frames, k + offset))
        r["sent"] += 1
        k += 1
    state["finished"] = True
    if not sent:
        done.set()
    try:
        await asyncio.wait_for(done.wait(), WAIT_S)
    except asyncio.TimeoutError:
        r["errors"].append(f"{len(sent)} frames neither answered nor counted dropped")
    receiver.cancel()


async def paced_session(url, frames, fps, duration_s, start_at, offset=0):
    """One session of the latency run."""
    r = counters()
    try:
        async with connect(url) as ws:
            await pump(ws, frames, fps, start_at, start_at + duration_s, offset, r)
            await ws.close(1000)
    except Exception as e:  # noqa: BLE001 - reported, not raised
        r["errors"].append(f"{type(e).__name__}: {e}")
    return r


def closed_by_server(o, e):
    """Records the close code of a session the server closed (ConnectionClosed `e`); one not
    documented is wrong."""
    o["close"] = e.rcvd.code if e.rcvd else None
    if o["close"] not in DOCUMENTED:
        o["why"] = o["why"] or f"closed by the server: {e}"


# ---------------------------------------------------------------------------------------
# RFC 6455 on a raw socket


def ws_frame(opcode, payload):
    """A client frame (FIN, masked)."""
    mask = os.urandom(4)
    n = len(payload)
    head = bytes([0x80 | opcode])
    if n < 126:
        head += bytes([0x80 | n])
    elif n < 1 << 16:
        head += bytes([0x80 | 126]) + struct.pack("!H", n)
    else:
        head += bytes([0x80 | 127]) + struct.pack("!Q", n)
    masked = bytes(b ^ mask[i % 4] for i, b in enumerate(payload)) if n < 4096 else (
        (int.from_bytes(payload, "big") ^ int.from_bytes((mask * (n // 4 + 1))[:n], "big"))
        .to_bytes(n, "big"))
    return head + mask + masked


async def raw_open(url):
    """A WebSocket handshake on a raw socket: (reader, writer) once the server said 101."""
    u = urllib.parse.urlsplit(url)
    reader, writer = await asyncio.open_connection(u.hostname, u.port)
    key = base64.b64encode(os.urandom(16)).decode()
    path = u.path + (f"?{u.query}" if u.query else "")
    writer.write((f"GET {path} HTTP/1.1\r\nHost: {u.netloc}\r\nUpgrade: websocket\r\n"
                  f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
                  "Sec-WebSocket-Version: 13\r\n\r\n").encode())
    head = await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), WAIT_S)
    status = head.split(b"\r\n", 1)[0]
    if b" 101 " not in status:
        raise RuntimeError(f"no upgrade: {status!r}")
    return reader, writer


async def raw_message(reader):
    """The server's next message: ("text", str) or ("close", code)."""
    data, opcode = b"", None
    while True:
        b0, b1 = await asyncio.wait_for(reader.readexactly(2), WAIT_S)
        n = b1 & 0x7F
        if n == 126:
            n = struct.unpack("!H", await reader.readexactly(2))[0]
        elif n == 127:
            n = struct.unpack("!Q", await reader.readexactly(8))[0]
        payload = await reader.readexactly(n)
        op = b0 & 0x0F
        if op == 8:
            return "close", struct.unpack("!H", payload[:2])[0] if len(payload) >= 2 else None
        if op in (9, 10):
            continue
        opcode = opcode or op
        data += payload
        if b0 & 0x80:
            return ("text" if opcode == 1 else "binary"), data.decode(errors="replace")


def rst(writer):
    """Aborts the connection with a TCP reset (SO_LINGER 0)."""
    sock = writer.get_extra_info("socket")
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
    writer.transport.abort()


# ---------------------------------------------------------------------------------------
# the soak


class Soak:
    """Slots of clients, each reconnecting after every end until the deadline; every session
    ends in `outcomes`: kind, answers, the close code the server sent (None when the client cut
    the connection), and `ok`: answered or closed with a documented code, and nothing wrong
    seen (`why`)."""

    def __init__(self, url, frames, fps, idle_timeout_s, deadline, seed):
        self.url, self.frames, self.fps = url, frames, fps
        self.idle_timeout_s, self.deadline, self.seed = idle_timeout_s, deadline, seed
        self.outcomes = []

    async def slot(self, i, kind):
        """Sessions of `kind` one after another until the deadline."""
        j = 0
        while time.monotonic() < self.deadline:
            rng = random.Random(self.seed * 1_000_003 + i * 10_007 + j)
            o = {"kind": kind, "slot": i, "n": j, "answers": 0, "dropped": 0, "close": None,
                 "problem_codes": {}, "why": ""}
            t0 = time.monotonic()
            try:
                await getattr(self, kind)(o, rng)
            except (ConnectionResetError, asyncio.IncompleteReadError) as e:
                if kind == "disconnect" and o["answers"] == 0:
                    # The server's 1013 lost to the reset our frame caused: reconciled with
                    # stream_sessions_refused_total by the soak's checks.
                    o["close"] = "reset before an answer"
                else:
                    o["why"] = f"{type(e).__name__}: {e}"
            except Exception as e:  # noqa: BLE001 - an outcome, not a crash of the soak
                o["why"] = (o["why"] + f"; {type(e).__name__}: {e}").strip("; ")
            o["seconds"] = round(time.monotonic() - t0, 2)
            o["ok"] = not o["why"] and (o["answers"] > 0 or o["close"] in DOCUMENTED
                                        or o["close"] == "reset before an answer")
            if isinstance(o["close"], int) and o["close"] not in DOCUMENTED:
                o["ok"] = False
            self.outcomes.append(o)
            j += 1
            if o["answers"] == 0:
                await asyncio.sleep(rng.uniform(0.5, 1.0))  # try again later, as 1013 asks

    async def normal(self, o, rng):
        """30-240 frames at the soak's rate, every one answered or counted dropped; close
        1000, which the server echoes."""
        r = counters()
        n = rng.randint(30, 240)
        try:
            async with connect(self.url) as ws:
                start = time.monotonic()
                await pump(ws, self.frames, self.fps, start, start + n / self.fps,
                           rng.randrange(len(self.frames)), r)
                await ws.close(1000)
            o["close"] = ws.close_code
        except ConnectionClosed as e:
            closed_by_server(o, e)
        o["answers"] += len(r["latencies_ms"])  # every answer, problems included
        o["dropped"] += r["dropped"]
        o["problem_codes"] = r["problem_codes"]
        if r["errors"]:
            o["why"] = "; ".join(r["errors"][:3])

    async def disconnect(self, o, rng):
        """One or two frames answered, then the connection cut in the middle of a frame
        (within its header or its payload; FIN or reset), or reset with frames in flight."""
        variant = rng.choice(["cut-header", "cut-payload", "cut-payload-rst", "rst-in-flight"])
        o["variant"] = variant
        reader, writer = await raw_open(self.url)
        for k in range(rng.randint(1, 2)):
            writer.write(ws_frame(1, json.dumps({"frame_id": k}).encode()))
            writer.write(ws_frame(2, rng.choice(self.frames)))
            await writer.drain()
            kind, body = await raw_message(reader)
            if kind == "close":  # refused (1013) before the cut
                o["close"] = body
                o["why"] = "" if body in DOCUMENTED else f"closed with {body}"
                rst(writer)
                return
            if kind != "text" or "frame" not in json.loads(body):
                o["why"] = f"expected an answer, got {kind} {body!r:.80}"
                rst(writer)
                return
            o["answers"] += 1
        full = ws_frame(2, rng.choice(self.frames))
        if variant == "cut-header":
            part = full[:rng.randint(1, 9)]
        elif variant == "rst-in-flight":
            part = full + ws_frame(2, rng.choice(self.frames))
        else:
            part = full[:rng.randint(15, len(full) - 1)]
        writer.write(part)
        await writer.drain()
        if variant.endswith("rst") or variant == "rst-in-flight":
            rst(writer)
        else:
            writer.close()
            await writer.wait_closed()

    async def garbage(self, o, rng):
        """Random binary (noise, a truncated JPEG, a JPEG header and noise) and text that is
        no frame meta, each answered by its problem in order; then a real frame, answered."""
        try:
            await self._garbage(o, rng)
        except ConnectionClosed as e:
            closed_by_server(o, e)

    async def _garbage(self, o, rng):
        binaries = 0  # an answer's frame.index: frames received before (for a text message:
        async with connect(self.url) as ws:  # the index of the frame it would apply to)
            for k in range(rng.randint(3, 12)):
                what = rng.choice(["noise", "truncated-jpeg", "jpeg-head", "text", "meta"])
                if what == "noise":
                    await ws.send(rng.randbytes(rng.randint(1, 65536)))
                elif what == "truncated-jpeg":
                    f = rng.choice(self.frames)
                    await ws.send(f[:rng.randint(2, len(f) - 2)])
                elif what == "jpeg-head":
                    await ws.send(b"\xff\xd8\xff\xe0" + rng.randbytes(rng.randint(1, 4096)))
                elif what == "text":
                    await ws.send("x" + "".join(chr(rng.randint(32, 0x2FFF))
                                                for _ in range(rng.randint(0, 200))))
                else:
                    await ws.send(rng.choice(['{"frame_id": true}', '{"capture_time_ms": "x"}',
                                              '{"prior": 5}', '{"frame_id": ', "null"]))
                answer = json.loads(await asyncio.wait_for(ws.recv(), WAIT_S))
                if "frame" not in answer or answer["frame"]["index"] != binaries:
                    o["why"] = f"message {k} ({what}): answer {str(answer)[:120]}"
                    return
                binaries += what in ("noise", "truncated-jpeg", "jpeg-head")
                o["answers"] += 1
                if "markers" not in answer:
                    c = answer.get("code", "?")
                    o["problem_codes"][c] = o["problem_codes"].get(c, 0) + 1
                elif what in ("noise", "jpeg-head", "text", "meta"):
                    o["why"] = f"{what} answered as a frame: {str(answer)[:120]}"
            await ws.send(json.dumps({"frame_id": "after-garbage"}))
            await ws.send(rng.choice(self.frames))
            answer = json.loads(await asyncio.wait_for(ws.recv(), WAIT_S))
            o["answers"] += 1
            if answer.get("frame", {}).get("id") != "after-garbage":
                o["why"] = f"the frame after the garbage: {str(answer)[:120]}"
            await ws.close(1000)
        o["close"] = ws.close_code

    async def stall(self, o, rng):
        """One frame, answered; then silence until the server closes (1008 at its idle
        timeout)."""
        async with connect(self.url) as ws:
            try:
                await ws.send(json.dumps({"frame_id": 0}))
                await ws.send(rng.choice(self.frames))
                json.loads(await asyncio.wait_for(ws.recv(), WAIT_S))
            except ConnectionClosed as e:  # refused (1013) before it could stall
                closed_by_server(o, e)
                return
            o["answers"] += 1
            t = time.monotonic()
            try:
                message = await asyncio.wait_for(ws.recv(), self.idle_timeout_s + 30)
                o["why"] = f"a message to a silent client: {str(message)[:80]}"
            except ConnectionClosed as e:
                o["close"] = e.rcvd.code if e.rcvd else None
            o["closed_after_s"] = round(time.monotonic() - t, 1)
        if o["close"] != 1008:
            o["why"] = o["why"] or f"closed with {o['close']}, not 1008"


async def close_code(ws):
    """The code of the close the server sends, and the answers before it."""
    answers = 0
    try:
        while True:
            await asyncio.wait_for(ws.recv(), WAIT_S)
            answers += 1
    except ConnectionClosed as e:
        return (e.rcvd.code if e.rcvd else None), answers


async def final_phase(server, url, a, sessions_open):
    """With the server started here: `--max-stream-sessions` sessions open, one more is
    closed with 1013; then SIGTERM, and every open session is closed with 1001 (half of them
    with a frame just sent). `sessions_open()` reads the server's gauge."""
    import signal

    conns = [await connect(url) for _ in range(a.session_limit)]
    for _ in range(100):
        if sessions_open() == a.session_limit:
            break
        await asyncio.sleep(0.1)
    async with connect(url) as extra:
        extra_code, _ = await close_code(extra)
    for ws in conns[::2]:
        await ws.send(json.dumps({"frame_id": 0}))
        await ws.send(a.frames_bytes[0])
    server.proc.send_signal(signal.SIGTERM)
    closes = await asyncio.gather(*[close_code(ws) for ws in conns])
    codes = {}
    for code, _ in closes:
        codes[str(code)] = codes.get(str(code), 0) + 1
    return {"session_limit": a.session_limit, "extra_session_close": extra_code,
            "sigterm_closes": codes,
            "answers_before_1001": sum(n for _, n in closes),
            "checks": {f"session {a.session_limit + 1} of --max-stream-sessions "
                       f"{a.session_limit} closed with 1013": extra_code == 1013,
                       "SIGTERM closes every open session with 1001":
                           codes == {"1001": a.session_limit}}}


# ---------------------------------------------------------------------------------------
# one checked session (docker/smoke.sh, through the balancer)


async def checked_session(base_url, frames, query):
    """Sends each frame after its meta and waits for its answer: each answer in order, with
    `tracks`; the codes tracked by the last frame; a close with 1000, echoed."""
    rid = f"stream-smoke-{os.getpid()}-{int(time.time())}"
    url = f"{base_url.replace('http', 'ws', 1)}/v1/stream?{query}"
    out = {"request_id": rid, "answers": 0, "why": "", "close": None}
    async with connect(url, additional_headers={"X-Request-Id": rid}) as ws:
        for k, frame in enumerate(frames):
            await ws.send(json.dumps({"frame_id": k, "capture_time_ms": k * 1000 / 30}))
            await ws.send(frame)
            answer = json.loads(await asyncio.wait_for(ws.recv(), WAIT_S))
            fr = answer.get("frame", {})
            if fr.get("id") != k or fr.get("index") != k or "tracks" not in answer:
                out["why"] = f"answer {k}: {str(answer)[:200]}"
                break
            out["answers"] += 1
            out["tracks"] = {t["id"]: t["status"] for t in answer["tracks"]}
            out["markers"] = len(answer["markers"])
        await ws.close(1000)
    out["close"] = ws.close_code
    tracking = [t for t, s in out.get("tracks", {}).items() if s == "tracking"]
    if not out["why"] and not tracking:
        out["why"] = f"no track is tracking after {len(frames)} frames: {out.get('tracks')}"
    if not out["why"] and out["close"] != 1000:
        out["why"] = f"closed with {out['close']}"
    out["ok"] = not out["why"]
    return out
