// The HMI end to end: Debian's headless Chromium driven by Playwright against a real
// `rtcnc serve` on the simulated mill. One machine, one operator session going through a
// shift in order (log in, upload, preview, run, hold, override, MDI, jog, e-stop, alarm),
// then a viewer. Each screen is checked with axe-core and saved as a screenshot in
// target/hmi-screenshots (two of them are committed in docs/).
import assert from 'node:assert/strict';
import { mkdirSync, readFileSync } from 'node:fs';
import { join } from 'node:path';
import { after, before, describe, it } from 'node:test';
import { chromium } from 'playwright-core';
import { CHROMIUM_ARGS, REPO, USERS, chromiumPath, loginToken, startServer } from './server.mjs';

const SHOTS = process.env.RTCNC_SCREENSHOTS ?? join(REPO, 'target', 'hmi-screenshots');
const AXE = readFileSync(join(REPO, 'web', 'node_modules', 'axe-core', 'axe.min.js'), 'utf8');

let server, browser, page, token;
/** Keep-alives from the page to the server are dropped while this is set. */
let dropKeepAlives = false;
const sockets = [];

async function until(what, f, timeoutMs = 20_000, everyMs = 50) {
  const end = Date.now() + timeoutMs;
  let last;
  while (Date.now() < end) {
    last = await f();
    if (last) return last;
    await new Promise((r) => setTimeout(r, everyMs));
  }
  // What the machine was doing, for the report.
  const s = await status().catch(() => null);
  const faults = await fetch(`${server.url}/api/faults`, { headers: { Authorization: `Bearer ${token}` } })
    .then((r) => r.json())
    .catch(() => []);
  const machine = s ? `state ${s.state}, mode ${s.mode}, line ${s.line}, at ${JSON.stringify(s.machine_position)}, overrides ${JSON.stringify(s.overrides)}` : 'no status';
  throw new Error(`timed out waiting for ${what}; last ${JSON.stringify(last)}; ${machine}; last faults ${JSON.stringify(faults.slice(-3).map((f) => `${f.code}: ${f.message}`))}`);
}

async function status() {
  const r = await fetch(`${server.url}/api/status`, { headers: { Authorization: `Bearer ${token}` } });
  return r.json();
}

async function screen(name) {
  await page.click(`nav a[href="/${name}"]`);
  await page.waitForSelector(`main.screen-${name}`);
}

/** No serious or critical axe-core violation on what the page shows now. */
async function accessible(what) {
  await page.evaluate(AXE);
  const found = await page.evaluate(async () => {
    const r = await window.axe.run(document, { resultTypes: ['violations'] });
    return r.violations.filter((v) => v.impact === 'serious' || v.impact === 'critical').map((v) => `${v.id} (${v.impact}): ${v.help} at ${v.nodes.map((n) => n.target.join(' ')).slice(0, 3).join(', ')}`);
  });
  assert.deepEqual(found, [], `${what}: axe-core violations`);
}

async function shot(name) {
  await page.screenshot({ path: join(SHOTS, `${name}.png`) });
}

/** Pixels of the tool path's canvas that are not its background. */
async function drawnPixels(testid) {
  return page.evaluate((id) => {
    const c = document.querySelector(`[data-testid="${id}"] canvas`);
    const copy = document.createElement('canvas');
    copy.width = c.width;
    copy.height = c.height;
    const g = copy.getContext('2d');
    g.drawImage(c, 0, 0);
    const d = g.getImageData(0, 0, c.width, c.height).data;
    // The path's colours are bright; the background and the grid are dark.
    let bright = 0;
    for (let i = 0; i < d.length; i += 4) if (d[i] + d[i + 1] + d[i + 2] > 400) bright++;
    return bright;
  }, testid);
}

before(async () => {
  mkdirSync(SHOTS, { recursive: true });
  server = await startServer();
  token = await loginToken(server.url, 'viewer');
  browser = await chromium.launch({ executablePath: chromiumPath(), args: CHROMIUM_ARGS });
  const context = await browser.newContext({ viewport: { width: 1280, height: 800 } });
  page = await context.newPage();
  page.on('pageerror', (e) => console.error('page error:', e.message));
  await page.routeWebSocket(/\/api\/ws/, (ws) => {
    const upstream = ws.connectToServer();
    sockets.push(ws);
    ws.onMessage((m) => {
      if (dropKeepAlives && String(m).includes('jog_keep_alive')) return;
      upstream.send(m);
    });
    upstream.onMessage((m) => ws.send(m));
  });
});

after(async () => {
  await browser?.close();
  await server?.stop();
});

describe('an operator', () => {
  it('logs in', async () => {
    await page.goto(server.url);
    await page.waitForSelector('[data-testid=login-submit]');
    await accessible('log-in');
    await shot('login');
    await page.fill('input[name=user]', 'operator');
    await page.fill('input[name=password]', USERS.operator[1]);
    await page.click('[data-testid=login-submit]');
    await page.waitForSelector('[data-testid=dro]');
    // Control needs the lease: disabled, with the reason.
    assert.equal(await page.getAttribute('[data-testid=reset]', 'data-why'), 'take the control first');
    await page.click('[data-testid=lease-take]');
    await page.waitForSelector('[data-testid=lease-release]');
    await page.click('[data-testid=reset]');
    await until('idle', async () => (await status()).state === 'idle');
    await page.waitForSelector('[data-testid=state]:has-text("Idle")');
  });

  it('uploads examples/bracket.ngc and the preview shows its path', async () => {
    await screen('programs');
    await page.setInputFiles('[data-testid=upload-input]', join(REPO, 'examples', 'bracket.ngc'));
    await page.waitForSelector('[data-testid="open-bracket.ngc"]');
    // The preview holds the points of the API's preview, and they are drawn.
    const r = await fetch(`${server.url}/api/programs/bracket.ngc/preview`, { headers: { Authorization: `Bearer ${token}` } });
    const p = await r.json();
    const points = 1 + p.paths.reduce((n, x) => n + x.points.length - 1, 0);
    await until('preview', async () => Number(await page.getAttribute('[data-testid=preview-toolpath]', 'data-points')) === points);
    await page.click('[data-testid=preview-toolpath] button:has-text("Top")');
    await until('drawn path', async () => (await drawnPixels('preview-toolpath')) > 300, 5000);
    // The editor checks as one types: an error at its line.
    await page.click('[data-testid=editor]');
    await page.keyboard.press('Control+Home');
    await page.keyboard.type('G1 X(\n');
    await page.waitForSelector('[data-testid=editor-errors] li');
    const err = await page.textContent('[data-testid=editor-errors] li');
    assert.match(err, /line 1, column 5/);
    assert.equal(await page.getAttribute('[data-testid=save-version]', 'data-why'), 'the program has errors');
    await page.keyboard.press('Control+Home');
    await page.keyboard.press('Shift+ArrowDown');
    await page.keyboard.press('Delete');
    await until('no errors', async () => (await page.textContent('[data-testid=check-state]')) === 'no errors');
    assert.match(await page.textContent('[data-testid=save-version]'), /bracket-v2\.ngc/);
    await accessible('programs');
    await shot('programs');
    // Back to the file as stored, then load it.
    await page.click('[data-testid="open-bracket.ngc"]');
    await until('loadable', async () => (await page.getAttribute('[data-testid=preview-load]', 'data-why')) === null);
    await page.click('[data-testid=preview-load]');
    await until('loaded', async () => (await status()).program === 'bracket.ngc');
  });

  it('runs it: the DRO and the run path advance, an override changes the path speed, feed hold stops and resume goes on', async () => {
    await screen('operate');
    await page.waitForSelector('[data-testid=program-name]:has-text("bracket.ngc")');
    // Feed override to 50 % with the slider's keys (5 % a step).
    await page.focus('[data-testid=override-feed-slider]');
    for (let i = 0; i < 10; i++) await page.keyboard.press('ArrowLeft');
    await until('feed 50 %', async () => Math.abs((await status()).overrides.feed - 0.5) < 1e-9);
    await page.click('[data-testid=cycle-start]');
    await until('running', async () => (await status()).state === 'running');
    const x0 = await page.textContent('[data-testid=dro-work-X]');
    // Lines 9-15 are feeds at F1200 (20 mm/s): at 50 % the path runs at 10 mm/s.
    const slow = await until('10 mm/s on a F1200 line', async () => {
      const s = await status();
      return s.line >= 9 && s.line <= 15 && Math.abs(s.path_speed - 10) < 0.5 && s;
    }, 30_000, 20);
    assert.ok(slow.overrides.feed === 0.5);
    assert.notEqual(await page.textContent('[data-testid=dro-work-X]'), x0, 'the DRO advanced');
    // Distance to go on line 9 (G1 X60 from X-5): shown, and what the status says.
    await until('distance to go on line 9', async () => {
      const s = await status();
      const shown = Number((await page.textContent('[data-testid=dro-togo-X]')).replace('−', '-'));
      return s.line === 9 && shown > 1 && shown < 65 && Math.abs(shown - (60 - (await status()).machine_position.X)) < 5;
    }, 10_000, 20);
    const run1 = Number(await page.getAttribute('[data-testid=operate-toolpath]', 'data-executed'));
    assert.ok(run1 > 0, `the run path advanced (${run1})`);
    await page.click('[data-testid=override-feed-slider] ~ button:has-text("100 %")');
    await until('20 mm/s at 100 %', async () => {
      const s = await status();
      return s.line >= 9 && s.line <= 15 && s.overrides.feed === 1 && Math.abs(s.path_speed - 20) < 0.5;
    }, 15_000, 20);
    await shot('operate');
    // Feed hold: the path decelerates and stands.
    await page.click('[data-testid=feed-hold]');
    await until('held', async () => (await status()).state === 'held');
    await until('standing', async () => (await status()).path_speed === 0);
    const a = (await status()).machine_position;
    await new Promise((r) => setTimeout(r, 500));
    assert.deepEqual((await status()).machine_position, a, 'no motion in feed hold');
    await page.waitForSelector('[data-testid=resume]');
    await accessible('operate, held');
    await page.click('[data-testid=resume]');
    await until('moving again', async () => {
      const s = await status();
      return s.state === 'running' && JSON.stringify(s.machine_position) !== JSON.stringify(a);
    });
    const run2 = Number(await page.getAttribute('[data-testid=operate-toolpath]', 'data-executed'));
    assert.ok(run2 >= run1, 'the run path never goes back');
    await until('further along', async () => Number(await page.getAttribute('[data-testid=operate-toolpath]', 'data-executed')) > run2);
    await page.click('[data-testid=stop]');
    await until('stopped', async () => (await status()).state === 'idle');
  });

  it('homes one axis and switches the mode', async () => {
    await screen('manual');
    const before = (await status()).joints.map((j) => j.homed);
    await page.click('[data-testid=home-Z]');
    await until('Z homed', async () => {
      const s = await status();
      return s.state === 'idle' && s.joints[2].homed && Math.abs(s.machine_position.Z) < 1e-9;
    }, 60_000);
    assert.deepEqual((await status()).joints.map((j) => j.homed).slice(0, 2), before.slice(0, 2), 'X and Y keep their state');
    await page.waitForSelector('[data-testid=dro-homed-Z]:has-text("yes")');
    await page.click('[data-testid=mode-mdi]');
    await until('MDI mode', async () => (await status()).mode === 'mdi');
    await page.waitForSelector('[data-testid=mode-mdi][aria-pressed=true]');
    await page.click('[data-testid=mode-manual]');
    await until('manual mode', async () => (await status()).mode === 'manual');
  });

  it('moves with MDI G0', async () => {
    await page.fill('[data-testid=mdi-input]', 'G0 X12 Y20 Z-1');
    await page.press('[data-testid=mdi-input]', 'Enter');
    await until('at X12 Y20 Z-1', async () => {
      const s = await status();
      const p = s.machine_position;
      return s.state === 'idle' && Math.abs(p.X - 12) < 1e-6 && Math.abs(p.Y - 20) < 1e-6 && Math.abs(p.Z + 1) < 1e-6;
    });
    await page.waitForSelector('[data-testid=dro-work-X]:has-text("12.000")');
    await page.waitForSelector('[data-testid=mdi-history] li:has-text("G0 X12 Y20 Z-1")');
  });

  it('jogs while the keep-alives come, and the machine stops the axis when they stop', async () => {
    const box = await page.locator('[data-testid="jog-X+"]').boundingBox();
    await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
    await page.mouse.down();
    const x0 = (await status()).machine_position.X;
    await until('jogging', async () => (await status()).machine_position.X > x0 + 2);
    // The button stays held; the keep-alives no longer reach the machine.
    dropKeepAlives = true;
    const t0 = Date.now();
    await until('stopped', async () => {
      const s = await status();
      return s.state === 'idle' && s.joints[0].velocity === 0;
    }, 5000, 10);
    const x1 = (await status()).machine_position.X;
    await new Promise((r) => setTimeout(r, 400));
    assert.equal((await status()).machine_position.X, x1, 'X stands while the button is still held');
    assert.ok(Date.now() - t0 < 3000);
    await page.mouse.up();
    dropKeepAlives = false;
    await accessible('manual');
    await shot('manual');
  });

  it('e-stops, sees the alarm, acknowledges it and resets', async () => {
    await page.click('[data-testid=estop]');
    await until('e-stop', async () => (await status()).state === 'estop');
    await page.waitForSelector('[data-testid=state]:has-text("E-stop")');
    await page.waitForSelector('nav .badge');
    await screen('diagnostics');
    const row = page.locator('[data-testid=alarm-list] tr.open', { hasText: 'kernel.estop' }).first();
    await row.waitFor();
    await row.locator('button:has-text("Acknowledge")').click();
    await until('acknowledged', async () => {
      const r = await fetch(`${server.url}/api/faults`, { headers: { Authorization: `Bearer ${token}` } });
      const f = await r.json();
      return f.some((x) => x.code === 'kernel.estop') && f.filter((x) => x.code === 'kernel.estop').every((x) => x.acknowledged);
    });
    await page.waitForSelector('[data-testid=alarm-list] tr.acked:has-text("kernel.estop")');
    await page.click('[data-testid=reset]');
    await until('idle again', async () => (await status()).state === 'idle');
    await accessible('diagnostics');
  });

  it('sees the live plots, the task timing and the PLC signals', async () => {
    await page.waitForSelector('[data-testid=timing] tbody tr');
    await page.fill('input[placeholder^="door"]', 'door_closed');
    await page.click('button[aria-label="Watch MILL.DOOR_CLOSED"]');
    await page.waitForSelector('[data-testid="plc-value-MILL.DOOR_CLOSED"]:has-text("1")');
    await page.waitForTimeout(600);
    await shot('diagnostics');
  });

  it('edits setup only where the role allows', async () => {
    await screen('setup');
    await page.waitForSelector('[data-testid=tool-table] tbody tr');
    assert.match(await page.getAttribute('[data-testid=tools-save]', 'data-why'), /setters and admins only/);
    assert.match(await page.getAttribute('[data-testid=machine-save]', 'data-why'), /admins only/);
    await accessible('setup');
    await shot('setup');
  });

  it('sees the banner when the connection is lost, and it goes when the link is back', async () => {
    await screen('operate');
    for (const ws of sockets.splice(0)) await ws.close().catch(() => {});
    await page.waitForSelector('[data-testid=link-banner]');
    assert.notEqual(await page.getAttribute('[data-testid=reset]', 'data-why'), null);
    await page.waitForSelector('[data-testid=link-banner]', { state: 'detached', timeout: 15_000 });
  });
});

describe('a viewer', () => {
  it('cannot start a program: the control is disabled with the reason, and the API refuses it', async () => {
    const context = await browser.newContext({ viewport: { width: 1280, height: 800 } });
    const viewer = await context.newPage();
    await viewer.goto(server.url);
    await viewer.fill('input[name=user]', 'viewer');
    await viewer.fill('input[name=password]', USERS.viewer[1]);
    await viewer.click('[data-testid=login-submit]');
    await viewer.waitForSelector('[data-testid=cycle-start]');
    assert.ok(await viewer.isDisabled('[data-testid=cycle-start]'));
    assert.match(await viewer.getAttribute('[data-testid=cycle-start]', 'data-why'), /operators only: you are logged in as viewer/);
    assert.ok(await viewer.isDisabled('[data-testid=estop]'));
    assert.ok(await viewer.isDisabled('[data-testid=lease-take]'));
    const r = await fetch(`${server.url}/api/control/cycle-start`, { method: 'POST', headers: { Authorization: `Bearer ${token}`, 'content-type': 'application/json' }, body: '{}' });
    assert.equal(r.status, 403);
    assert.equal((await r.json()).code, 'auth.forbidden');
    await context.close();
  });
});
