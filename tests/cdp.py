#!/usr/bin/env python3
# cdp.py - drive headless Chromium through the DevTools protocol for tests/browser.sh
# (standard library only: a minimal WebSocket client).  Usage:
#   cdp.py CHROMIUM WxH URL ACTION...
# Actions, in order:  wait:MS   shot:FILE   run:SHELL-COMMAND
#   until:JS-EXPRESSION:MS (poll until truthy or fail)   eval:JS-EXPRESSION (print it)
#   mark (remember the time)   since:JS-EXPRESSION (print the expression's number, in
#   milliseconds since the epoch, minus the marked time)
#   press:X,Y  move:X,Y  release:X,Y (the left mouse button, in CSS pixels)
#   drag:X,Y,DX,DY,N (press at X,Y and move N times by DX,DY, each move waiting for the
#   page's next picture through its hook frepDebug.after(n): print the median and the
#   largest time from a move to its picture, in ms, then the list; the button stays down)
# Exit status 0 when every action succeeded.
import base64, json, os, re, socket, struct, subprocess, sys, tempfile, time, urllib.request


class WS:
    def __init__(self, url):
        m = re.match(r'ws://([^:/]+):(\d+)(/.*)', url)
        self.s = socket.create_connection((m.group(1), int(m.group(2))), timeout=60)
        key = base64.b64encode(os.urandom(16)).decode()
        self.s.sendall(('GET %s HTTP/1.1\r\nHost: %s:%s\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n'
                        'Sec-WebSocket-Key: %s\r\nSec-WebSocket-Version: 13\r\n\r\n'
                        % (m.group(3), m.group(1), m.group(2), key)).encode())
        head = b''
        while b'\r\n\r\n' not in head:
            head += self.s.recv(1)
        self.n = 0

    def send(self, obj):
        data = json.dumps(obj).encode()
        n = len(data)
        hdr = bytes([0x81]) + (bytes([0x80 | n]) if n < 126 else
                               bytes([0x80 | 126]) + struct.pack('>H', n) if n < 65536 else
                               bytes([0x80 | 127]) + struct.pack('>Q', n))
        mask = os.urandom(4)
        self.s.sendall(hdr + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(data)))

    def recv_exact(self, n):
        b = b''
        while len(b) < n:
            c = self.s.recv(n - len(b))
            if not c:
                raise EOFError
            b += c
        return b

    def recv(self):
        msg = b''
        while True:
            b0, b1 = self.recv_exact(2)
            n = b1 & 127
            if n == 126:
                n, = struct.unpack('>H', self.recv_exact(2))
            elif n == 127:
                n, = struct.unpack('>Q', self.recv_exact(8))
            msg += self.recv_exact(n)
            if b0 & 0x80:
                return json.loads(msg)

    def call(self, method, **params):
        self.n += 1
        self.send({'id': self.n, 'method': method, 'params': params})
        while True:
            r = self.recv()
            if r.get('id') == self.n:
                if 'error' in r:
                    raise RuntimeError(str(r['error']))
                return r.get('result', {})


def evaluate(ws, expr):
    r = ws.call('Runtime.evaluate', expression=expr, returnByValue=True)
    return r.get('result', {}).get('value')


# Chromium started and its page's DevTools socket open: a start can fail on a loaded
# machine (no DevTools line within the wait, a refused first connection); it is tried
# again this many times, each with a fresh profile.
LAUNCH_ATTEMPTS = 3


def launch(chromium, w, h):
    """Start chromium: (process, profile directory, page socket), or raise."""
    profile = tempfile.mkdtemp(prefix='frep-cdp-')
    p = subprocess.Popen([chromium, '--headless=new', '--no-sandbox', '--disable-gpu',
                          '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--hide-scrollbars',
                          '--no-first-run', '--user-data-dir=' + profile, '--window-size=%s,%s' % (w, h),
                          '--remote-debugging-port=0', 'about:blank'],
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        port = None
        t0 = time.time()
        while port is None and time.time() - t0 < 60:
            line = p.stderr.readline()
            if not line and p.poll() is not None:
                break
            m = re.search(r'DevTools listening on ws://127.0.0.1:(\d+)/', line)
            if m:
                port = m.group(1)
        if port is None:
            raise RuntimeError('chromium gave no DevTools port')
        targets = json.load(urllib.request.urlopen('http://127.0.0.1:%s/json/list' % port))
        page = [t for t in targets if t.get('type') == 'page'][0]
        return p, profile, WS(page['webSocketDebuggerUrl'])
    except Exception:
        p.terminate()
        p.wait()
        subprocess.run(['rm', '-rf', profile])
        raise


def main():
    chromium, size, url, actions = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4:]
    w, h = size.split('x')
    for attempt in range(LAUNCH_ATTEMPTS):
        try:
            p, profile, ws = launch(chromium, w, h)
            break
        except Exception as e:
            print('cdp: chromium start %d failed: %s' % (attempt + 1, e), file=sys.stderr)
            if attempt + 1 == LAUNCH_ATTEMPTS:
                raise
    ok = True
    try:
        ws.call('Page.enable')
        ws.call('Page.navigate', url=url)
        mark = time.time()
        for a in actions:
            kind, _, arg = a.partition(':')
            if kind == 'wait':
                time.sleep(int(arg) / 1000.0)
            elif kind == 'shot':
                data = ws.call('Page.captureScreenshot', format='png')['data']
                open(arg, 'wb').write(base64.b64decode(data))
            elif kind == 'run':
                subprocess.run(arg, shell=True, check=True)
            elif kind in ('press', 'move', 'release'):
                x, y = (float(v) for v in arg.split(','))
                ws.call('Input.dispatchMouseEvent', x=x, y=y, button='left',
                        type={'press': 'mousePressed', 'move': 'mouseMoved', 'release': 'mouseReleased'}[kind],
                        buttons=0 if kind == 'release' else 1, clickCount=1 if kind != 'move' else 0)
            elif kind == 'drag':
                x, y, dx, dy, n = (float(v) for v in arg.split(','))
                ws.call('Input.dispatchMouseEvent', x=x, y=y, button='left', type='mousePressed',
                        buttons=1, clickCount=1)
                times = []
                for i in range(1, int(n) + 1):
                    n0 = evaluate(ws, 'frepDebug.frames')
                    t1 = time.time()
                    ws.call('Input.dispatchMouseEvent', x=x + i * dx, y=y + i * dy, button='left',
                            type='mouseMoved', buttons=1)
                    ws.call('Runtime.evaluate', expression='frepDebug.after(%d)' % n0,
                            awaitPromise=True, returnByValue=True)
                    times.append((time.time() - t1) * 1000)
                s = sorted(times)
                print('%.0f %.0f %s' % (s[len(s) // 2], s[-1], ','.join('%.0f' % t for t in times)))
            elif kind == 'mark':
                mark = time.time()
            elif kind == 'until':
                expr, _, ms = arg.rpartition(':')
                t1 = time.time()
                while not evaluate(ws, expr):
                    if time.time() - t1 > int(ms) / 1000.0:
                        print('timed out waiting for ' + expr)
                        ok = False
                        break
                    time.sleep(0.02)
                if not ok:
                    break
            elif kind == 'eval':
                print(evaluate(ws, arg))
            elif kind == 'since':
                v = evaluate(ws, arg)
                print('%d' % (float(v) - mark * 1000) if v is not None else 'none')
    finally:
        p.terminate()
        p.wait()
        subprocess.run(['rm', '-rf', profile])
    sys.exit(0 if ok else 1)


if __name__ == '__main__':
    main()
