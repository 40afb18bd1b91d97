// Loads a page in headless Chromium (WebGL on SwiftShader) and prints what the page's
// `window.result` (a promise of a string) resolves to. Chromium is driven over its DevTools pipe
// (--remote-debugging-pipe: JSON messages ended by NUL on fds 3 and 4), so the wait is for the
// page's own work (module imports, image decoding, GPU read-backs), however long it takes, up to
// the time limit.
// Usage: PRTBAKE_CHROMIUM_PROFILE=DIR node chromium_page.mjs CHROMIUM URL [SECONDS]
import { spawn } from 'node:child_process';
import { mkdtempSync, rmSync } from 'node:fs';

const [chromium, url, secondsText] = process.argv.slice(2);
const profile = process.env.PRTBAKE_CHROMIUM_PROFILE;
// Chromium's own temporary files (its singleton socket folder) go into a folder of ours,
// removed when this script exits, instead of staying in /tmp. It is short: the socket's
// path must fit in 108 bytes.
const tmp = mkdtempSync('/tmp/prtbake-chromium-');
process.on('exit', () => rmSync(tmp, { recursive: true, force: true }));
const proc = spawn(chromium, [
  '--headless', '--no-sandbox', '--disable-gpu', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
  '--allow-file-access-from-files', '--disable-background-networking', '--disable-component-update', '--no-first-run',
  `--user-data-dir=${profile}`, '--remote-debugging-pipe', 'about:blank',
], { stdio: ['ignore', 'ignore', 'ignore', 'pipe', 'pipe'], env: { ...process.env, TMPDIR: tmp } });
const timer = setTimeout(() => {
  process.stdout.write('ERROR the page gave no result within the time limit\n');
  proc.kill('SIGKILL');
  process.exit(3);
}, Number(secondsText || 120) * 1000);

let nextId = 1, buffer = '';
const pending = new Map();
function send(method, params = {}, sessionId = undefined) {
  return new Promise((resolve, reject) => {
    const id = nextId++;
    pending.set(id, { resolve, reject });
    proc.stdio[3].write(JSON.stringify({ id, method, params, ...(sessionId ? { sessionId } : {}) }) + '\0');
  });
}
proc.stdio[4].on('data', (chunk) => {
  buffer += chunk.toString('utf8');
  for (let end = buffer.indexOf('\0'); end >= 0; end = buffer.indexOf('\0')) {
    const msg = JSON.parse(buffer.slice(0, end));
    buffer = buffer.slice(end + 1);
    const p = msg.id && pending.get(msg.id);
    if (!p) continue;
    pending.delete(msg.id);
    if (msg.error) p.reject(new Error(JSON.stringify(msg.error)));
    else p.resolve(msg.result);
  }
});

const { targetId } = await send('Target.createTarget', { url });
const { sessionId } = await send('Target.attachToTarget', { targetId, flatten: true });
// Waits for window.result to exist, then for it to settle. Retried while the page is still
// navigating (the evaluation's context is then destroyed).
const expression = `new Promise((resolve) => {
  const poll = () => window.result ? window.result.then(resolve, (e) => resolve('ERROR ' + e)) : setTimeout(poll, 50);
  poll();
})`;
let value;
for (;;) {
  try {
    value = (await send('Runtime.evaluate', { expression, awaitPromise: true, returnByValue: true }, sessionId)).result.value;
    break;
  } catch (e) {
    if (!/context was destroyed|Cannot find context/.test(String(e))) throw e;
    await new Promise((r) => setTimeout(r, 100));
  }
}
process.stdout.write(String(value) + '\n');
clearTimeout(timer);
proc.kill('SIGKILL');
