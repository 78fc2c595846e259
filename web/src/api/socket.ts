// The live link: the WebSocket of the API (`GET /api/ws`): a snapshot, then merge patches
// of the status at the rate asked for, events, trace samples, a heartbeat every second.
// It reconnects by itself; a silence of more than `SILENCE_MS` counts as a lost link.
import type { Event, Status } from './types';

export const SILENCE_MS = 2500;

export interface TraceSample {
  cycle: number;
  time_s: number;
  line: number;
  path_speed: number;
  setpoint: number[];
  feedback: number[];
  following_error: number[];
}

export type ServerMessage =
  | { type: 'snapshot'; status: Status; last_seq: number; user: string; role: string }
  | { type: 'status'; changes: Partial<Status> }
  | { type: 'event'; event: Event }
  | { type: 'events_lost'; count: number }
  | { type: 'trace'; samples: TraceSample[] }
  | { type: 'trace_lost'; batches: number }
  | { type: 'heartbeat'; machine_connected: boolean; last_seq: number }
  | { type: 'subscribed'; rate_hz: number }
  | { type: 'closing'; reason: string }
  | { type: 'pong'; id: number }
  | { type: 'error'; problem: { code: string; detail: string } };

/** A status with a merge patch applied (RFC 7396 at the top level, as the server sends). */
export function applyPatch(status: Status, changes: Partial<Status>): Status {
  return { ...status, ...changes };
}

export interface LinkHandlers {
  onMessage(m: ServerMessage): void;
  onOpen(): void;
  onClose(reason: string): void;
}

export interface Subscription {
  rate_hz: number;
  events: boolean;
  trace: boolean;
  trace_decimation: number;
}

export class LiveLink {
  private ws: WebSocket | null = null;
  private retry = 0;
  private lastHeard = 0;
  private watchdog: ReturnType<typeof setInterval> | null = null;
  private stopped = false;
  private open = false;
  subscription: Subscription = { rate_hz: 50, events: true, trace: false, trace_decimation: 10 };

  constructor(
    private url: () => string,
    private handlers: LinkHandlers,
  ) {}

  start() {
    this.stopped = false;
    this.connect();
    this.watchdog = setInterval(() => {
      if (this.open && performance.now() - this.lastHeard > SILENCE_MS) {
        // Heard nothing, not even the heartbeat: the link is gone even if the socket is not
        // closed yet (a cable pulled).
        this.ws?.close();
        this.lost('no message from the server for ' + (SILENCE_MS / 1000).toFixed(1) + ' s');
      }
    }, 500);
  }

  stop() {
    this.stopped = true;
    if (this.watchdog) clearInterval(this.watchdog);
    this.ws?.close();
    this.ws = null;
  }

  get connected(): boolean {
    return this.open;
  }

  send(message: object): boolean {
    if (!this.open || !this.ws || this.ws.readyState !== WebSocket.OPEN) return false;
    this.ws.send(JSON.stringify(message));
    return true;
  }

  subscribe(s: Partial<Subscription>) {
    this.subscription = { ...this.subscription, ...s };
    this.send({ type: 'subscribe', ...this.subscription });
  }

  private connect() {
    if (this.stopped) return;
    const ws = new WebSocket(this.url());
    this.ws = ws;
    ws.onopen = () => {
      this.open = true;
      this.retry = 0;
      this.lastHeard = performance.now();
      ws.send(JSON.stringify({ type: 'subscribe', ...this.subscription }));
      this.handlers.onOpen();
    };
    ws.onmessage = (e) => {
      this.lastHeard = performance.now();
      let m: ServerMessage;
      try {
        m = JSON.parse(e.data as string);
      } catch {
        return;
      }
      this.handlers.onMessage(m);
    };
    ws.onclose = () => {
      if (this.ws !== ws) return;
      this.lost('the connection closed');
      const delay = Math.min(5000, 250 * 2 ** this.retry++);
      setTimeout(() => this.connect(), delay);
    };
  }

  private lost(reason: string) {
    if (!this.open) return;
    this.open = false;
    this.handlers.onClose(reason);
  }
}
