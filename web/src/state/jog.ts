// Continuous jog held by a key or a button: the jog starts on press, a keep-alive goes to
// the machine every `KEEP_ALIVE_MS` while it is held (the machine stops a jog 200 ms after
// its last keep-alive), and a release, a lost focus or a lost link stops it. Without a link
// no keep-alive leaves, so the machine stops the axis by itself.

export const KEEP_ALIVE_MS = 100;

export interface JogTransport {
  /** Starts a continuous jog (the API's `POST /api/control/jog`). */
  start(axis: string, velocity: number): Promise<void>;
  /** One keep-alive over the live link; false when the link is down. */
  keepAlive(axis: string): boolean;
  /** Stops the jog (`POST /api/control/jog/stop`). */
  stop(axis: string): Promise<void>;
  /**
   * Whether the machine still jogs: a jog the machine already stopped (its keep-alive
   * lapsed) is not stopped again, which the kernel would refuse and record.
   */
  jogging(axis: string): boolean;
}

export interface Timers {
  setInterval(f: () => void, ms: number): unknown;
  clearInterval(id: unknown): void;
}

interface Held {
  timer: unknown;
  started: Promise<boolean>;
}

export class JogController {
  private held = new Map<string, Held>();

  constructor(
    private transport: JogTransport,
    private onError: (axis: string, error: unknown) => void = () => {},
    private timers: Timers = {
      setInterval: (f, ms) => setInterval(f, ms),
      clearInterval: (id) => clearInterval(id as ReturnType<typeof setInterval>),
    },
  ) {}

  /** Axes being jogged. */
  get axes(): string[] {
    return [...this.held.keys()];
  }

  press(axis: string, velocity: number) {
    if (this.held.has(axis) || velocity === 0) return;
    const started = this.transport.start(axis, velocity).then(
      () => true,
      (e) => {
        this.drop(axis);
        this.onError(axis, e);
        return false;
      },
    );
    const timer = this.timers.setInterval(() => {
      if (!this.transport.keepAlive(axis)) {
        // The link is gone: stop sending; the machine stops the axis without keep-alives.
        this.drop(axis);
        this.onError(axis, new Error('the link to the machine is lost: the machine stops the jog'));
      }
    }, KEEP_ALIVE_MS);
    this.held.set(axis, { timer, started });
  }

  release(axis: string) {
    const h = this.held.get(axis);
    if (!h) return;
    this.drop(axis);
    void h.started.then((ok) => {
      if (ok && this.transport.jogging(axis)) this.transport.stop(axis).catch((e) => this.onError(axis, e));
    });
  }

  releaseAll() {
    for (const axis of this.axes) this.release(axis);
  }

  private drop(axis: string) {
    const h = this.held.get(axis);
    if (h) this.timers.clearInterval(h.timer);
    this.held.delete(axis);
  }
}

/** The keyboard's jog keys (LinuxCNC AXIS's): arrows X and Y, Page Up/Down Z. */
export const JOG_KEYS: Record<string, [axis: string, direction: 1 | -1]> = {
  ArrowLeft: ['X', -1],
  ArrowRight: ['X', 1],
  ArrowDown: ['Y', -1],
  ArrowUp: ['Y', 1],
  PageDown: ['Z', -1],
  PageUp: ['Z', 1],
};
