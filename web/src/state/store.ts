// The HMI's state: the session, the live status (snapshot plus merge patches from the
// WebSocket), the lease, events and alarms, notices for the operator, the loaded program's
// tool path and how far the run has gone along it.
import { batch, computed, signal } from '@preact/signals';
import { ApiError, api, apiBytes, getToken, setToken } from '../api/client';
import { type Cursor, type PathChain, advance, decodePreview, indexOfLine } from '../api/preview';
import { LiveLink, type ServerMessage, type TraceSample, applyPatch } from '../api/socket';
import type { Ack, ApiInfo, Event, FaultRecord, Lease, SessionInfo, Status } from '../api/types';
import type { Need, Who } from './permissions';
import { whyNot } from './permissions';

export interface Session {
  user: string;
  role: string;
  passwordChangeRequired: boolean;
}

export interface Notice {
  id: number;
  tone: 'info' | 'error';
  text: string;
}

export const session = signal<Session | null>(null);
export const info = signal<ApiInfo | null>(null);
export const status = signal<Status | null>(null);
/** The WebSocket is open. */
export const linkUp = signal(false);
/** Why the link is down (for the banner). */
export const linkDownReason = signal<string | null>(null);
export const holdsLease = signal(false);
export const events = signal<Event[]>([]);
export const faults = signal<FaultRecord[]>([]);
export const notices = signal<Notice[]>([]);
/** The loaded program's tool path and the run's progress along it. */
export const loadedChain = signal<PathChain | null>(null);
export const cursor = signal<Cursor>({ index: 0 });
/** Machine time at the last cycle start, for the elapsed time. */
export const cycleStartedAt = signal<number | null>(null);
export const estimateS = signal<number | null>(null);
/** Trace samples arrive here when a plot asked for them. */
export const traceListeners = new Set<(s: TraceSample[]) => void>();
/** Status changes, for views that draw outside of Preact (three.js). */
export const statusListeners = new Set<(s: Status) => void>();

export const connected = computed(() => linkUp.value && (status.value?.connected ?? false));

export const who = computed<Who>(() => ({
  role: session.value?.role ?? 'viewer',
  holdsLease: holdsLease.value,
  leaseHolder: status.value?.lease_holder,
  connected: connected.value,
}));

/** Why a control that needs `need` is not allowed, or null. */
export function reason(need: Need): string | null {
  return whyNot(need, who.value);
}

export const unacknowledged = computed(() => faults.value.filter((f) => !f.acknowledged).length);

let noticeId = 0;
export function notify(text: string, tone: Notice['tone'] = 'info') {
  const id = ++noticeId;
  notices.value = [...notices.value.slice(-4), { id, tone, text }];
  setTimeout(() => (notices.value = notices.value.filter((n) => n.id !== id)), tone === 'error' ? 8000 : 4000);
}

export function errorText(e: unknown): string {
  if (e instanceof ApiError) return e.detail ? `${e.detail} (${e.code})` : e.code;
  return e instanceof Error ? e.message : String(e);
}

/** Runs a command; a refusal becomes an error notice. */
export async function run<T>(what: string, f: () => Promise<T>): Promise<T | undefined> {
  try {
    return await f();
  } catch (e) {
    notify(`${what}: ${errorText(e)}`, 'error');
    return undefined;
  }
}

// ----- the live link ------------------------------------------------------------------

export const link = new LiveLink(
  () => `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/api/ws?token=${encodeURIComponent(getToken() ?? '')}`,
  {
    onOpen() {
      batch(() => {
        linkUp.value = true;
        linkDownReason.value = null;
      });
      void refreshFaults();
      void refreshLease();
    },
    onClose(why) {
      batch(() => {
        linkUp.value = false;
        linkDownReason.value = why;
      });
    },
    onMessage: onServerMessage,
  },
);

function onServerMessage(m: ServerMessage) {
  switch (m.type) {
    case 'snapshot':
      setStatus(m.status);
      break;
    case 'status':
      if (status.value) setStatus(applyPatch(status.value, m.changes));
      break;
    case 'event':
      onEvent(m.event);
      break;
    case 'trace':
      for (const l of traceListeners) l(m.samples);
      break;
    case 'closing':
      linkDownReason.value = m.reason;
      if (m.reason.includes('expired')) void logout('the session expired: log in again');
      break;
    case 'error':
      notify(`${m.problem.detail} (${m.problem.code})`, 'error');
      break;
    default:
      break;
  }
}

let lastLeaseHolder: string | null | undefined;
let lastProgram: string | null | undefined;

function setStatus(s: Status) {
  const before = status.value;
  status.value = s;
  if (s.lease_holder !== lastLeaseHolder) {
    lastLeaseHolder = s.lease_holder;
    void refreshLease();
  }
  if (s.program !== lastProgram) {
    lastProgram = s.program;
    void loadChain(s.program ?? null);
  }
  // A new run: the path starts again.
  if (s.state === 'running' && s.mode === 'auto' && before && !(before.state === 'running' && before.mode === 'auto')) {
    if (before.state !== 'held' && before.state !== 'paused') {
      cursor.value = { index: runFromIndex };
      cycleStartedAt.value = s.time_s;
      runFromIndex = 0;
    }
  }
  const chain = loadedChain.value;
  if (chain && s.mode === 'auto' && s.line > 0 && s.state !== 'idle') {
    const next = advance(chain, cursor.value, s.line, toolInChainFrame(s));
    if (next.index !== cursor.value.index) cursor.value = next;
  }
  if (s.program_ended && s.state === 'idle' && chain && before && !before.program_ended) {
    cursor.value = { index: chain.count - 1 };
  }
  for (const l of statusListeners) l(s);
}

/** The tool's position in the preview's frame (the canonical frame: no tool length offset), mm. */
export function toolInChainFrame(s: Status): [number, number, number] {
  const mm = s.modal?.units === 'inch' ? 25.4 : 1;
  const p = s.machine_position;
  const t = s.modal?.tool_offset ?? {};
  return [(p.X ?? 0) - (t.X ?? 0) * mm, (p.Y ?? 0) - (t.Y ?? 0) * mm, (p.Z ?? 0) - (t.Z ?? 0) * mm];
}

let runFromIndex = 0;
/** Marks where a run from a line starts on the path. */
export function startingFrom(line: number) {
  const chain = loadedChain.value;
  runFromIndex = chain && line > 1 ? indexOfLine(chain, line) : 0;
}

function onEvent(e: Event) {
  events.value = [...events.value.slice(-499), e];
  if (e.kind === 'fault') {
    notify(`Alarm: ${e.message}`, 'error');
    void refreshFaults();
  } else if (e.kind === 'message') {
    notify(`Message: ${e.message}`);
  } else if (e.kind === 'machine_lost') {
    notify('The machine process does not answer', 'error');
  }
}

export async function refreshFaults() {
  try {
    faults.value = await api<FaultRecord[]>('/api/faults');
  } catch {
    /* the banner tells */
  }
}

export async function refreshLease() {
  try {
    const l = await api<Lease>('/api/lease');
    holdsLease.value = l.mine;
  } catch {
    holdsLease.value = false;
  }
}

export async function refreshEvents() {
  try {
    const page = await api<{ events: Event[] }>('/api/events', { query: { since: 0, limit: 500 } });
    events.value = page.events;
  } catch {
    /* the banner tells */
  }
}

const chainCache = new Map<string, PathChain>();

/** The tool path of a stored program (binary preview), cached by name until uploaded again. */
export async function fetchChain(name: string, fresh = false): Promise<PathChain> {
  const cached = chainCache.get(name);
  if (cached && !fresh) return cached;
  const buf = await apiBytes('/api/programs/{name}/preview', { params: { name }, query: { format: 'binary' } });
  const chain = decodePreview(buf);
  chainCache.clear();
  chainCache.set(name, chain);
  return chain;
}

export function forgetChain(name: string) {
  chainCache.delete(name);
}

async function loadChain(name: string | null) {
  batch(() => {
    loadedChain.value = null;
    cursor.value = { index: 0 };
    estimateS.value = null;
  });
  if (!name) return;
  try {
    loadedChain.value = await fetchChain(name);
  } catch (e) {
    notify(`Preview of ${name}: ${errorText(e)}`, 'error');
  }
  try {
    const est = await api<{ cycle_time_s: number; ended: boolean }>('/api/programs/{name}/estimate', { params: { name } });
    if (status.value?.program === name) estimateS.value = est.ended ? est.cycle_time_s : null;
  } catch {
    /* shown as unknown */
  }
}

// ----- session ------------------------------------------------------------------------

const TOKEN_KEY = 'rtcnc.token';

export async function login(user: string, password: string) {
  const s = await api<SessionInfo>('/api/session', { method: 'POST', json: { user, password } });
  setToken(s.token ?? null);
  sessionStorage.setItem(TOKEN_KEY, s.token ?? '');
  await started(s);
}

async function started(s: SessionInfo) {
  session.value = { user: s.user, role: s.role, passwordChangeRequired: s.password_change_required };
  holdsLease.value = s.holds_lease;
  if (s.password_change_required) return;
  info.value = await api<ApiInfo>('/api');
  link.start();
  void refreshEvents();
}

/** Takes up a session of this browser tab again after a reload. */
export async function resume(): Promise<boolean> {
  const t = sessionStorage.getItem(TOKEN_KEY);
  if (!t) return false;
  setToken(t);
  try {
    await started(await api<SessionInfo>('/api/session'));
    return true;
  } catch {
    setToken(null);
    sessionStorage.removeItem(TOKEN_KEY);
    return false;
  }
}

export async function changePassword(old: string, next: string) {
  await api('/api/session/password', { method: 'POST', json: { old, new: next } });
  const s = await api<SessionInfo>('/api/session');
  await started(s);
}

export async function logout(message?: string) {
  jogStopAll?.();
  link.stop();
  try {
    if (getToken()) await api('/api/session', { method: 'DELETE' });
  } catch {
    /* gone already */
  }
  setToken(null);
  sessionStorage.removeItem(TOKEN_KEY);
  batch(() => {
    session.value = null;
    status.value = null;
    linkUp.value = false;
    holdsLease.value = false;
  });
  if (message) notify(message, 'error');
}

let jogStopAll: (() => void) | null = null;
export function onLogout(f: () => void) {
  jogStopAll = f;
}

// ----- commands -----------------------------------------------------------------------

/** A control command; waits for the kernel to take it. */
export function command(path: Parameters<typeof api>[0], json: unknown = {}, params?: Record<string, string>): Promise<Ack> {
  return api<Ack>(path, { method: 'POST', json, params });
}

export async function takeLease(takeOver = false) {
  await api<Lease>('/api/lease', { method: 'POST', query: { take_over: takeOver } });
  holdsLease.value = true;
}

export async function releaseLease() {
  await api('/api/lease', { method: 'DELETE' });
  holdsLease.value = false;
}
