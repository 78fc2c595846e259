import { describe, expect, it } from 'vitest';
import { JOG_KEYS, JogController, KEEP_ALIVE_MS, type JogTransport } from '../src/state/jog';

/** A clock the test moves by hand. */
function fakeTimers() {
  let now = 0;
  let next = 1;
  const timers = new Map<number, { f: () => void; every: number; at: number }>();
  return {
    timers: {
      setInterval: (f: () => void, ms: number) => {
        const id = next++;
        timers.set(id, { f, every: ms, at: now + ms });
        return id;
      },
      clearInterval: (id: unknown) => void timers.delete(id as number),
    },
    advance(ms: number) {
      const end = now + ms;
      for (;;) {
        const due = [...timers.entries()].filter(([, t]) => t.at <= end).sort((a, b) => a[1].at - b[1].at)[0];
        if (!due) break;
        now = due[1].at;
        due[1].at += due[1].every;
        due[1].f();
      }
      now = end;
    },
    get running() {
      return timers.size;
    },
  };
}

function transport(linkUp = { value: true }, jogging = { value: true }) {
  const log: string[] = [];
  const t: JogTransport = {
    start: async (axis, v) => void log.push(`start ${axis} ${v}`),
    keepAlive: (axis) => {
      if (!linkUp.value) return false;
      log.push(`keep ${axis}`);
      return true;
    },
    stop: async (axis) => void log.push(`stop ${axis}`),
    jogging: () => jogging.value,
  };
  return { t, log };
}

const settle = () => new Promise((r) => setTimeout(r, 0));

describe('a held jog', () => {
  it('sends a keep-alive every 100 ms while held, well inside the machine 200 ms', async () => {
    const clock = fakeTimers();
    const { t, log } = transport();
    const jog = new JogController(t, () => {}, clock.timers);
    jog.press('X', 20);
    clock.advance(1000);
    expect(KEEP_ALIVE_MS).toBeLessThanOrEqual(100);
    expect(log.filter((l) => l === 'keep X')).toHaveLength(10);
    expect(log[0]).toBe('start X 20');
    jog.release('X');
    await settle();
    expect(log.at(-1)).toBe('stop X');
    clock.advance(1000);
    expect(log.filter((l) => l === 'keep X')).toHaveLength(10);
    expect(clock.running).toBe(0);
  });

  it('stops sending when the link is lost, so the machine stops the axis; the release then sends nothing the machine would refuse', async () => {
    const clock = fakeTimers();
    const link = { value: true };
    const jogging = { value: true };
    const { t, log } = transport(link, jogging);
    const errors: string[] = [];
    const jog = new JogController(t, (axis, e) => errors.push(`${axis}: ${(e as Error).message}`), clock.timers);
    jog.press('Y', -5);
    clock.advance(250);
    link.value = false;
    clock.advance(1000);
    expect(jog.axes).toEqual([]);
    expect(errors).toHaveLength(1);
    expect(clock.running).toBe(0);
    jogging.value = false;
    jog.release('Y');
    await settle();
    expect(log).not.toContain('stop Y');
  });

  it('a second press of a held axis starts nothing; releaseAll lets every axis go', async () => {
    const clock = fakeTimers();
    const { t, log } = transport();
    const jog = new JogController(t, () => {}, clock.timers);
    jog.press('X', 1);
    jog.press('X', 1);
    jog.press('Z', -1);
    expect(log.filter((l) => l.startsWith('start'))).toEqual(['start X 1', 'start Z -1']);
    jog.releaseAll();
    await settle();
    expect(log.filter((l) => l.startsWith('stop')).sort()).toEqual(['stop X', 'stop Z']);
  });

  it('a refused start stops the keep-alives and reports the refusal', async () => {
    const clock = fakeTimers();
    const { t, log } = transport();
    t.start = async () => {
      throw new Error('the machine is busy');
    };
    const errors: unknown[] = [];
    const jog = new JogController(t, (_a, e) => errors.push(e), clock.timers);
    jog.press('X', 10);
    await settle();
    clock.advance(500);
    expect(log.filter((l) => l.startsWith('keep'))).toEqual([]);
    expect(errors).toHaveLength(1);
  });

  it('the keys are those of LinuxCNC AXIS', () => {
    expect(JOG_KEYS.ArrowRight).toEqual(['X', 1]);
    expect(JOG_KEYS.ArrowDown).toEqual(['Y', -1]);
    expect(JOG_KEYS.PageUp).toEqual(['Z', 1]);
  });
});
