// The HMI's figures for docs/hmi.md, in Debian's headless Chromium against a real
// `rtcnc serve` on the simulated mill (RTCNC_BIN picks the build; bench/hmi.sh uses the
// release one):
//   1. frame time on Operate while examples/bracket.ngc runs and status comes at 50 Hz;
//   2. time to load and draw the preview of a 1 000 000-segment program;
//   3. the bundle's size (raw and gzip).
import { readdirSync, readFileSync, statSync } from 'node:fs';
import { join } from 'node:path';
import { gzipSync } from 'node:zlib';
import { chromium } from 'playwright-core';
import { CHROMIUM_ARGS, REPO, USERS, chromiumPath, loginToken, startServer } from '../e2e/server.mjs';

const SEGMENTS = Number(process.env.SEGMENTS ?? 1_000_000);
const SECONDS = Number(process.env.SECONDS ?? 10);

function pct(xs, p) {
  const s = [...xs].sort((a, b) => a - b);
  return s[Math.min(s.length - 1, Math.floor((p / 100) * s.length))];
}

async function until(f, timeoutMs, everyMs = 20) {
  const end = Date.now() + timeoutMs;
  while (Date.now() < end) {
    const v = await f();
    if (v) return v;
    await new Promise((r) => setTimeout(r, everyMs));
  }
  throw new Error('timed out');
}

/**
 * SEGMENTS feed moves along an Archimedean spiral pocket (r from 1 to 70 mm, 0.4 mm
 * stepover), chords of 0.05-0.2 mm: dense CAM output, as an adaptive or spiral clearing.
 */
function bigProgram() {
  const lines = ['G21 G90 G17 G64 P0.01', 'G0 X1 Y0 Z1', 'G1 Z-1 F600', 'G1 F3000'];
  const turns = 69 / 0.4;
  for (let i = 1; i <= SEGMENTS; i++) {
    const th = (2 * Math.PI * turns * i) / SEGMENTS;
    const r = 1 + (69 * i) / SEGMENTS;
    lines.push(`X${(r * Math.cos(th)).toFixed(4)} Y${(r * Math.sin(th)).toFixed(4)}`);
  }
  lines.push('G0 Z5', 'M2', '');
  return lines.join('\n');
}

const server = await startServer({ extraArgs: ['--max-upload', String(64 << 20)] });
const browser = await chromium.launch({ executablePath: chromiumPath(), args: CHROMIUM_ARGS });
try {
  const page = await (await browser.newContext({ viewport: { width: 1280, height: 800 } })).newPage();
  let statusMessages = 0;
  await page.routeWebSocket(/\/api\/ws/, (ws) => {
    const up = ws.connectToServer();
    ws.onMessage((m) => up.send(m));
    up.onMessage((m) => {
      if (String(m).includes('"type":"status"')) statusMessages++;
      ws.send(m);
    });
  });
  await page.goto(server.url);
  await page.fill('input[name=user]', 'operator');
  await page.fill('input[name=password]', USERS.operator[1]);
  await page.click('[data-testid=login-submit]');
  await page.click('[data-testid=lease-take]');
  await page.waitForSelector('[data-testid=lease-release]');
  await page.click('[data-testid=reset]');
  await page.waitForSelector('[data-testid=state]:has-text("Idle")');
  const token = await loginToken(server.url, 'viewer');
  const auth = { Authorization: `Bearer ${token}` };

  // 1. Frame time while a program runs.
  await page.click('nav a[href="/programs"]');
  await page.setInputFiles('[data-testid=upload-input]', join(REPO, 'examples', 'bracket.ngc'));
  await page.waitForSelector('[data-testid="open-bracket.ngc"]');
  await until(async () => (await page.getAttribute('[data-testid=preview-load]', 'data-why')) === null, 20_000);
  await page.click('[data-testid=preview-load]');
  await page.click('nav a[href="/operate"]');
  await page.waitForSelector('[data-testid=program-name]:has-text("bracket.ngc")');
  await page.click('[data-testid=cycle-start]');
  await page.waitForSelector('[data-testid=state]:has-text("Running")');
  statusMessages = 0;
  const frames = await page.evaluate(async (seconds) => {
    const scene = window.__toolpath;
    const drawn0 = scene ? scene.frameMs.length : 0;
    const gaps = [];
    let last = performance.now();
    await new Promise((done) => {
      const end = last + seconds * 1000;
      const f = (t) => {
        gaps.push(t - last);
        last = t;
        if (t < end) requestAnimationFrame(f);
        else done();
      };
      requestAnimationFrame(f);
    });
    return { gaps: gaps.slice(1), render: scene ? scene.frameMs.slice(drawn0) : [] };
  }, SECONDS);
  const rate = statusMessages / SECONDS;
  const state = await (await fetch(`${server.url}/api/status`, { headers: auth })).json();
  console.log(`frame interval on Operate, program running (${frames.gaps.length} frames, ${rate.toFixed(1)} status messages/s received; machine ${state.state}):`);
  console.log(`  p50 ${pct(frames.gaps, 50).toFixed(1)} ms, p95 ${pct(frames.gaps, 95).toFixed(1)} ms, max ${Math.max(...frames.gaps).toFixed(1)} ms`);
  if (frames.render.length) {
    console.log(`  tool-path render per frame (${frames.render.length} renders): p50 ${pct(frames.render, 50).toFixed(2)} ms, p95 ${pct(frames.render, 95).toFixed(2)} ms`);
  }
  await page.click('[data-testid=stop]');
  await page.waitForSelector('[data-testid=state]:has-text("Idle")');

  // 2. The preview of a program of SEGMENTS segments.
  const text = bigProgram();
  const put = await fetch(`${server.url}/api/programs/big.ngc`, { method: 'PUT', headers: { Authorization: `Bearer ${await loginToken(server.url, 'operator')}` }, body: text });
  if (!put.ok) throw new Error(`upload: ${put.status} ${await put.text()}`);
  let t = performance.now();
  const bin = await fetch(`${server.url}/api/programs/big.ngc/preview?format=binary`, { headers: auth });
  const bytes = (await bin.arrayBuffer()).byteLength;
  const serverMs = performance.now() - t;
  const points = new DataView(await (await fetch(`${server.url}/api/programs/big.ngc/preview?format=binary`, { headers: auth })).arrayBuffer()).getUint32(8, true);
  console.log(`preview of ${SEGMENTS} segments (${(text.length / 1e6).toFixed(1)} MB of G-code): ${points} points, ${(bytes / 1e6).toFixed(1)} MB binary`);
  console.log(`  server: interpreted and sent in ${serverMs.toFixed(0)} ms (first request)`);
  await page.click('nav a[href="/programs"]');
  await page.waitForSelector('[data-testid="open-big.ngc"]');
  const drawnBefore = await page.evaluate(() => window.__toolpath?.frameMs.length ?? 0);
  t = performance.now();
  await page.click('[data-testid="open-big.ngc"]');
  await until(async () => Number(await page.getAttribute('[data-testid=preview-toolpath]', 'data-points')) === points, 120_000);
  const loadedMs = performance.now() - t;
  await until(async () => (await page.evaluate(() => window.__toolpath?.frameMs.length ?? 0)) > drawnBefore, 60_000, 5);
  const drawnMs = performance.now() - t;
  const [view, drawn] = await page.evaluate(() => [window.__toolpath.frameMs.slice(-1)[0], window.__toolpath.drawn]);
  console.log(`  browser: click to preview loaded ${loadedMs.toFixed(0)} ms, to first frame drawn ${drawnMs.toFixed(0)} ms (that frame's render ${view.toFixed(0)} ms; ${drawn} points drawn)`);

  // 3. The bundle.
  const dist = join(REPO, 'web', 'dist', 'assets');
  let raw = 0;
  let gz = 0;
  for (const f of readdirSync(dist)) {
    const b = readFileSync(join(dist, f));
    raw += statSync(join(dist, f)).size;
    gz += gzipSync(b).length;
    console.log(`  ${f}: ${(b.length / 1024).toFixed(0)} KiB, gzip ${(gzipSync(b).length / 1024).toFixed(0)} KiB`);
  }
  console.log(`bundle: ${(raw / 1024).toFixed(0)} KiB, gzip ${(gz / 1024).toFixed(0)} KiB`);
} finally {
  await browser.close();
  await server.stop();
}
