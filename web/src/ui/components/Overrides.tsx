import { useEffect, useRef, useState } from 'preact/hooks';
import { api } from '../../api/client';
import type { Ack } from '../../api/types';
import { percent } from '../../format';
import { reason, run, status } from '../../state/store';

const SLIDERS = [
  ['feed', 'Feed', 0, 2],
  ['rapid', 'Rapid', 0, 1],
  ['spindle', 'Spindle', 0.5, 1.5],
] as const;

/** Feed, rapid and spindle overrides: urgent commands, the next servo period has them. */
export function Overrides() {
  const s = status.value;
  const why = reason('lease');
  return (
    <section class="panel overrides" aria-label="Overrides">
      <h2>Overrides</h2>
      {SLIDERS.map(([key, label, min, max]) => (
        <Slider key={key} name={key} label={label} min={min} max={max} value={s?.overrides[key] ?? 1} why={why} />
      ))}
    </section>
  );
}

function Slider(props: { name: 'feed' | 'rapid' | 'spindle'; label: string; min: number; max: number; value: number; why: string | null }) {
  const { name, label, min, max, value, why } = props;
  const [dragging, setDragging] = useState<number | null>(null);
  const timer = useRef<ReturnType<typeof setTimeout> | null>(null);
  const send = (v: number) => {
    if (timer.current) clearTimeout(timer.current);
    timer.current = setTimeout(() => {
      void run(`${label} override`, () => api<Ack[]>('/api/control/overrides', { method: 'POST', json: { [name]: v } }));
    }, 60);
  };
  useEffect(() => () => void (timer.current && clearTimeout(timer.current)), []);
  // The slider shows what was asked until the machine reports it (or gives up on it). The
  // updaters compare with the newest request, not this render's: a report of an earlier
  // step arriving while the operator presses on must not put the slider back a step.
  useEffect(() => {
    if (dragging === null) return undefined;
    const asked = dragging;
    if (Math.abs(value - asked) < 1e-6) {
      setDragging((d) => (d === asked ? null : d));
      return undefined;
    }
    const t = setTimeout(() => setDragging((d) => (d === asked ? null : d)), 1500);
    return () => clearTimeout(t);
  }, [value, dragging]);
  const shown = dragging ?? value;
  const id = `ovr-${name}`;
  return (
    <div class="slider">
      <label for={id}>
        {label} <output data-testid={`override-${name}`}>{percent(value)}</output>
      </label>
      <div class="slider-row">
        <button type="button" class="btn small" disabled={!!why} title={why ?? undefined} aria-label={`${label} −10 %`} onClick={() => send(Math.max(min, Math.round((value - 0.1) * 10) / 10))}>
          −
        </button>
        <input
          id={id}
          type="range"
          min={min * 100}
          max={max * 100}
          step={5}
          value={Math.round(shown * 100)}
          disabled={!!why}
          title={why ?? undefined}
          data-testid={`override-${name}-slider`}
          onInput={(e) => {
            const v = Number(e.currentTarget.value) / 100;
            setDragging(v);
            send(v);
          }}
        />
        <button type="button" class="btn small" disabled={!!why} title={why ?? undefined} aria-label={`${label} +10 %`} onClick={() => send(Math.min(max, Math.round((value + 0.1) * 10) / 10))}>
          +
        </button>
        <button type="button" class="btn small" disabled={!!why} title={why ?? undefined} onClick={() => send(1)}>
          100 %
        </button>
      </div>
    </div>
  );
}
