import { signal } from '@preact/signals';
import { useEffect, useRef, useState } from 'preact/hooks';
import { api } from '../../api/client';
import type { MachineFile } from '../../api/types';
import { position } from '../../format';
import { JOG_KEYS, JogController } from '../../state/jog';
import { first, whyNotIdle } from '../../state/permissions';
import { command, errorText, info, link, notify, onLogout, reason, run, status } from '../../state/store';
import { Button, Why } from '../components/Button';
import { Dro } from '../components/Dro';

export const jog = new JogController(
  {
    start: (axis, velocity) => command('/api/control/jog', { axis, velocity }).then(() => undefined),
    keepAlive: (axis) => link.send({ type: 'jog_keep_alive', axis }),
    stop: (axis) => command('/api/control/jog/stop', { axis }).then(() => undefined),
    jogging: () => status.value?.mode === 'manual' && status.value?.state === 'running',
  },
  (axis, e) => notify(`Jog ${axis}: ${errorText(e)}`, 'error'),
);
onLogout(() => jog.releaseAll());
// A hidden tab or a lost focus lets go of every held jog.
addEventListener('blur', () => jog.releaseAll());
document.addEventListener('visibilitychange', () => document.hidden && jog.releaseAll());

const STEPS = [0.001, 0.01, 0.1, 1, 10];
const SPEEDS = [1, 5, 20, 50, 100];
const speed = signal(20);
const step = signal<number | null>(null);
const HISTORY_KEY = 'rtcnc.mdi-history';
const history = signal<string[]>(JSON.parse(localStorage.getItem(HISTORY_KEY) ?? '[]'));

function remember(line: string) {
  const next = [line, ...history.value.filter((l) => l !== line)].slice(0, 50);
  history.value = next;
  localStorage.setItem(HISTORY_KEY, JSON.stringify(next));
}

export function Manual() {
  const s = status.value;
  const axes = info.value?.axes ?? [];
  const why = first(reason('lease'), s?.state === 'running' && s.mode === 'manual' ? null : whyNotIdle(s?.state));
  // Keyboard jogging: arrows X/Y, Page Up/Down Z, held keys jog, released keys stop.
  useEffect(() => {
    const typing = (e: KeyboardEvent) => (e.target as HTMLElement).closest('input, textarea, select');
    const down = (e: KeyboardEvent) => {
      const k = JOG_KEYS[e.key];
      if (!k || typing(e) || !axes.includes(k[0])) return;
      e.preventDefault();
      if (e.repeat || reason('lease')) return;
      if (step.value === null) jog.press(k[0], k[1] * speed.value);
      else void run(`Jog ${k[0]}`, () => command('/api/control/jog', { axis: k[0], distance: k[1] * step.value! }));
    };
    const up = (e: KeyboardEvent) => {
      const k = JOG_KEYS[e.key];
      if (k) jog.release(k[0]);
    };
    addEventListener('keydown', down);
    addEventListener('keyup', up);
    return () => {
      removeEventListener('keydown', down);
      removeEventListener('keyup', up);
      jog.releaseAll();
    };
  }, [axes.join()]);
  return (
    <div class="manual">
      <div class="col left">
        <section class="panel" aria-label="Positions">
          <Dro />
        </section>
        <Homing />
        <TouchOff />
      </div>
      <div class="col middle">
        <section class="panel jog" aria-label="Jog">
          <h2>Jog</h2>
          <div class="choice" role="group" aria-label="Jog mode">
            <Button pressed={step.value === null} onClick={() => (step.value = null)}>
              Continuous
            </Button>
            {STEPS.map((d) => (
              <Button pressed={step.value === d} onClick={() => (step.value = d)} testid={`step-${d}`}>
                {d}
              </Button>
            ))}
          </div>
          <div class="choice" role="group" aria-label="Jog speed">
            <span>Speed (units/s)</span>
            {SPEEDS.map((v) => (
              <Button pressed={speed.value === v} onClick={() => (speed.value = v)}>
                {v}
              </Button>
            ))}
          </div>
          <div class="jog-grid">
            {axes.map((a) => (
              <div class="jog-axis" key={a}>
                <JogButton axis={a} direction={-1} why={why} />
                <span class="axis">{a}</span>
                <JogButton axis={a} direction={1} why={why} />
              </div>
            ))}
          </div>
          <Why why={why} />
          <p class="hint">Keys: ← → X, ↓ ↑ Y, Page Down / Page Up Z. Hold to jog; letting go, leaving the window or losing the link stops the axis.</p>
        </section>
        <Handwheel />
      </div>
      <div class="col right">
        <Mdi />
      </div>
    </div>
  );
}

function JogButton({ axis, direction, why }: { axis: string; direction: 1 | -1; why: string | null }) {
  const label = `${axis}${direction > 0 ? '+' : '−'}`;
  const press = (e: PointerEvent) => {
    if (why) return;
    (e.currentTarget as HTMLElement).setPointerCapture?.(e.pointerId);
    if (step.value === null) jog.press(axis, direction * speed.value);
    else void run(`Jog ${axis}`, () => command('/api/control/jog', { axis, distance: direction * step.value! }));
  };
  const release = () => jog.release(axis);
  return (
    <button
      type="button"
      class="btn jog-btn"
      disabled={!!why}
      title={why ?? `Hold to jog ${axis} ${direction > 0 ? 'plus' : 'minus'}`}
      data-testid={`jog-${axis}${direction > 0 ? '+' : '-'}`}
      onPointerDown={press}
      onPointerUp={release}
      onPointerCancel={release}
      onLostPointerCapture={release}
      onContextMenu={(e) => e.preventDefault()}
    >
      {label}
    </button>
  );
}

function Homing() {
  const s = status.value;
  const why = first(reason('lease'), whyNotIdle(s?.state));
  const axes = info.value?.axes ?? [];
  return (
    <section class="panel" aria-label="Homing">
      <h2>Homing</h2>
      <div class="buttons">
        <Button testid="home-all" tone="primary" why={why} onClick={() => run('Home', () => command('/api/control/home'))}>
          Home all
        </Button>
        {axes.map((a) => (
          <Button key={a} testid={`home-${a}`} why={why} onClick={() => run(`Home ${a}`, () => command('/api/control/home/{axis}', undefined, { axis: a }))}>
            Home {a}
          </Button>
        ))}
      </div>
      <h3>Mode</h3>
      <div class="choice" role="group" aria-label="Mode">
        {(['manual', 'mdi', 'auto'] as const).map((m) => (
          <Button
            key={m}
            testid={`mode-${m}`}
                        pressed={s?.mode === m}
            why={why}
            onClick={() => run(`Mode ${m}`, () => command('/api/control/mode', { mode: m }))}
          >
            {m === 'mdi' ? 'MDI' : m[0].toUpperCase() + m.slice(1)}
          </Button>
        ))}
      </div>
      <p class="hint">Cycle start, MDI, jog and homing also switch to the mode they need.</p>
    </section>
  );
}

function TouchOff() {
  const s = status.value;
  const axes = info.value?.axes ?? [];
  const [axis, setAxis] = useState(axes[0] ?? 'X');
  const [value, setValue] = useState('0');
  const system = s?.modal?.work_system ?? 'G54';
  const why = first(reason('lease'), whyNotIdle(s?.state));
  const v = Number(value);
  return (
    <section class="panel" aria-label="Touch-off">
      <h2>Touch-off</h2>
      <p class="hint">Sets the active work offset ({system}) so that the current position reads the value.</p>
      <div class="buttons">
        <label class="inline">
          Axis
          <select value={axis} onChange={(e) => setAxis(e.currentTarget.value)}>
            {axes.map((a) => (
              <option value={a}>{a}</option>
            ))}
          </select>
        </label>
        <label class="inline">
          reads
          <input type="number" step="any" value={value} onInput={(e) => setValue(e.currentTarget.value)} data-testid="touchoff-value" />
        </label>
        <Button
          testid="touch-off"
          tone="primary"
          why={first(why, Number.isFinite(v) && value.trim() !== '' ? null : 'give a number')}
          onClick={() =>
            run('Touch-off', async () => {
              await command('/api/control/mdi', { line: `G10 L20 P0 ${axis}${v}` });
              notify(`${system} ${axis}: now at ${position(v, s?.modal?.units)}`);
            })
          }
        >
          Set {axis}
        </Button>
      </div>
    </section>
  );
}

function Handwheel() {
  const axes = info.value?.axes ?? [];
  const [axis, setAxis] = useState<string | null>(null);
  const [scale, setScale] = useState(1);
  const [perCount, setPerCount] = useState<number | null>(null);
  const s = status.value;
  const why = first(reason('lease'), whyNotIdle(s?.state));
  useEffect(() => {
    api<MachineFile>('/api/setup/machine').then((f) => setPerCount(f.handwheel_units_per_count), () => undefined);
  }, []);
  const select = (a: string | null, sc: number) =>
    run('Handwheel', async () => {
      await command('/api/control/handwheel', { axis: a, scale: sc });
      setAxis(a);
      setScale(sc);
    });
  return (
    <section class="panel" aria-label="Handwheel">
      <h2>Handwheel</h2>
      <div class="choice" role="group" aria-label="Handwheel axis">
        {axes.map((a) => (
          <Button pressed={axis === a} why={why} onClick={() => select(a, scale)} testid={`handwheel-${a}`}>
            {a}
          </Button>
        ))}
        <Button pressed={axis === null} why={why} onClick={() => select(null, scale)}>
          Off
        </Button>
      </div>
      <div class="choice" role="group" aria-label="Handwheel scale">
        {[1, 10, 100].map((k) => (
          <Button pressed={scale === k} why={why} onClick={() => (axis ? select(axis, k) : setScale(k))}>
            ×{k}
          </Button>
        ))}
      </div>
      <p class="hint">
        {perCount !== null ? `${position(perCount * scale)} per count. ` : ''}
        The machine releases the handwheel at a feed hold or stop; the status does not report it, so this shows what was last chosen here.
      </p>
    </section>
  );
}

function Mdi() {
  const s = status.value;
  const [line, setLine] = useState('');
  const input = useRef<HTMLInputElement>(null);
  const why = first(reason('lease'), s?.state === 'idle' ? null : whyNotIdle(s?.state));
  const send = async (l: string) => {
    const text = l.trim();
    if (!text) return;
    remember(text);
    setLine('');
    await run('MDI', () => command('/api/control/mdi', { line: text }));
  };
  return (
    <section class="panel mdi" aria-label="MDI">
      <h2>MDI</h2>
      <form
        onSubmit={(e) => {
          e.preventDefault();
          if (!why) void send(line);
        }}
      >
        <label class="inline wide">
          Line
          <input ref={input} value={line} onInput={(e) => setLine(e.currentTarget.value)} data-testid="mdi-input" placeholder="G0 X10 Y10" autocomplete="off" />
        </label>
        <Button testid="mdi-send" tone="primary" why={why} onClick={() => void send(line)}>
          Send
        </Button>
      </form>
      <Why why={why} />
      <h3>History</h3>
      <ul class="history" data-testid="mdi-history">
        {history.value.map((h) => (
          <li key={h}>
            <button
              type="button"
              class="link mono"
              onClick={() => {
                setLine(h);
                input.current?.focus();
              }}
            >
              {h}
            </button>
          </li>
        ))}
      </ul>
    </section>
  );
}
