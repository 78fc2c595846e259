// Starts a real `rtcnc serve` on the simulated mill on a free port, in a scratch folder
// with its own users, programs, tool table and parameter file (as sdk/python/tests does).
import { spawn, spawnSync } from 'node:child_process';
import { copyFileSync, mkdtempSync, readFileSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';

export const REPO = resolve(dirname(fileURLToPath(import.meta.url)), '../..');
export const BIN = process.env.RTCNC_BIN ?? join(REPO, 'target', 'debug', 'rtcnc');

export const USERS = {
  admin: ['admin', 'admin-password-1'],
  setter: ['setter', 'setter-password-1'],
  operator: ['operator', 'operator-password-1'],
  viewer: ['viewer', 'viewer-password-1'],
};

/**
 * The mill's file, loosened like the Python tests': this VM stalls real-time threads for
 * milliseconds (docs/kernel.md "Timing"), and the mill's own following-error limits would
 * stop a program mid-test. `extra` is appended.
 */
function machineFile(folder, extra = '') {
  let text = readFileSync(join(REPO, 'configs', 'sim-mill.toml'), 'utf8');
  text = text.replace('min_ferror = 0.02, ferror = 0.2', 'min_ferror = 5.0, ferror = 5.0');
  text = text.replaceAll('min_ferror = 0.02, ferror = 0.2', 'min_ferror = 5.0, ferror = 5.0');
  text = text.replace('program = "../examples/plc/mill.st"', `program = "${REPO}/examples/plc/mill.st"`);
  text = text.replace('tool_table = "sim-mill.tbl"', 'tool_table = "sim-mill.tbl"\nparameters = "sim-mill.var"');
  copyFileSync(join(REPO, 'configs', 'sim-mill.tbl'), join(folder, 'sim-mill.tbl'));
  const path = join(folder, 'sim-mill.toml');
  writeFileSync(path, text + extra);
  return path;
}

export async function startServer({ extraArgs = [], extraConfig = '' } = {}) {
  const folder = mkdtempSync(join(tmpdir(), 'rtcnc-hmi-'));
  const config = machineFile(folder, extraConfig);
  const users = join(folder, 'users.toml');
  for (const [name, [role, password]] of Object.entries(USERS)) {
    const r = spawnSync(BIN, ['user', 'add', name, '--role', role, '--users', users, '--password-stdin'], { input: password + '\n' });
    if (r.status !== 0) throw new Error(`rtcnc user add: ${r.stderr}`);
  }
  const segment = `rtcnc-hmi-e2e-${process.pid}-${Date.now()}`;
  const child = spawn(BIN, ['serve', '--machine', config, '--listen', '127.0.0.1:0', '--users', users, '--programs', join(folder, 'programs'), '--segment', segment, ...extraArgs], {
    stdio: ['ignore', 'pipe', 'pipe'],
  });
  const log = [];
  let url = '';
  const onLine = (d) => {
    for (const line of String(d).split('\n')) {
      if (!line) continue;
      log.push(line);
      const m = /listening on (https?:\/\/\S+)/.exec(line);
      if (m) url = m[1];
    }
  };
  child.stdout.on('data', onLine);
  child.stderr.on('data', onLine);
  const deadline = Date.now() + 60_000;
  while (!url) {
    if (Date.now() > deadline || child.exitCode !== null) throw new Error('rtcnc serve did not start:\n' + log.join('\n'));
    await new Promise((r) => setTimeout(r, 50));
  }
  const server = { url, folder, config, child, log, stop: () => stopServer(server) };
  // Until the machine is attached.
  const token = await loginToken(url, 'viewer');
  while (true) {
    const r = await fetch(`${url}/api/status`, { headers: { Authorization: `Bearer ${token}` } }).catch(() => null);
    if (r?.ok && (await r.json()).connected) break;
    if (Date.now() > deadline) throw new Error('the machine did not attach:\n' + log.join('\n'));
    await new Promise((r) => setTimeout(r, 100));
  }
  return server;
}

export async function loginToken(url, user) {
  const r = await fetch(`${url}/api/session`, {
    method: 'POST',
    headers: { 'content-type': 'application/json' },
    body: JSON.stringify({ user, password: USERS[user][1] }),
  });
  if (!r.ok) throw new Error(`log-in ${user}: ${r.status} ${await r.text()}`);
  return (await r.json()).token;
}

async function stopServer(server) {
  writeFileSync(join(server.folder, 'serve.log'), server.log.join('\n') + '\n');
  if (server.child.exitCode !== null) return;
  server.child.kill('SIGTERM');
  await new Promise((r) => {
    const t = setTimeout(() => {
      server.child.kill('SIGKILL');
      r();
    }, 15_000);
    server.child.on('exit', () => {
      clearTimeout(t);
      r();
    });
  });
}

/** Debian's headless Chromium (scripts/setup.sh installs it); RTCNC_CHROMIUM names another. */
export function chromiumPath() {
  for (const p of [process.env.RTCNC_CHROMIUM, '/usr/lib/chromium/chromium-headless-shell', '/usr/bin/chromium']) {
    if (p && spawnSync('test', ['-x', p]).status === 0) return p;
  }
  throw new Error('no Chromium: scripts/setup.sh installs chromium-headless-shell (or set RTCNC_CHROMIUM)');
}

export const CHROMIUM_ARGS = ['--no-sandbox', '--disable-gpu', '--disable-background-networking', '--disable-component-update', '--disable-sync', '--no-first-run'];
