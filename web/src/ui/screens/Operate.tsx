import { signal } from '@preact/signals';
import { useEffect, useState } from 'preact/hooks';
import { apiText } from '../../api/client';
import { duration, feed, percent } from '../../format';
import { first, whyNotIdle } from '../../state/permissions';
import {
  command,
  cursor,
  cycleStartedAt,
  estimateS,
  loadedChain,
  reason,
  run,
  startingFrom,
  status,
  statusListeners,
} from '../../state/store';
import { Button } from '../components/Button';
import { Dro } from '../components/Dro';
import { Overrides } from '../components/Overrides';
import { ProgramText } from '../components/ProgramText';
import { ToolPath } from '../components/ToolPath';
import { ProgramPicker } from './Programs';

/** The loaded program's lines (fetched once per program). */
const programLines = signal<{ name: string; lines: string[] } | null>(null);

async function loadLines(name: string | null | undefined) {
  if (!name) {
    programLines.value = null;
    return;
  }
  if (programLines.value?.name === name) return;
  try {
    const text = await apiText('/api/programs/{name}', { params: { name } });
    programLines.value = { name, lines: text.split('\n') };
  } catch {
    programLines.value = { name, lines: [] };
  }
}

export const subscribeStatus = (f: (s: import('../../api/types').Status) => void) => {
  statusListeners.add(f);
  return () => void statusListeners.delete(f);
};

export function Operate() {
  const s = status.value;
  const [fromLine, setFromLine] = useState(0);
  useEffect(() => void loadLines(s?.program), [s?.program]);
  const lease = reason('lease');
  const idle = whyNotIdle(s?.state);
  const hasProgram = s?.program ? null : 'load a program first (Programs, or the list here)';
  const held = s?.state === 'held' || s?.state === 'paused';
  const running = s?.state === 'running' || s?.state === 'waiting_for_logic';
  const chain = loadedChain.value;
  const lines = programLines.value?.name === s?.program ? programLines.value?.lines ?? [] : [];
  return (
    <div class="operate">
      <div class="col left">
        <section class="panel" aria-label="Positions">
          <Dro />
        </section>
        <section class="panel program" aria-label="Program">
          <h2>
            Program <span class="program-name" data-testid="program-name">{s?.program ?? 'none loaded'}</span>
            <span class="line-no">line {s?.line ?? 0}</span>
          </h2>
          <ProgramText
            lines={lines}
            current={s?.mode === 'auto' ? s.line : 0}
            chosen={fromLine}
            onChoose={(n) => setFromLine(n === fromLine ? 0 : n)}
            label="Program text (tap a line to run from it)"
          />
          <ProgramPicker />
        </section>
      </div>
      <div class="col middle">
        <ToolPath chain={chain} executed={s?.mode === 'auto' || s?.program_ended ? cursor.value.index : -1} live subscribe={subscribeStatus} label="Tool path of the loaded program" testid="operate-toolpath" />
        <Progress />
      </div>
      <div class="col right">
        <section class="panel cycle" aria-label="Cycle">
          <h2>Cycle</h2>
          <div class="buttons">
            {held ? (
              <Button testid="resume" tone="go" why={lease} onClick={() => run('Resume', () => command('/api/control/resume'))}>
                Resume
              </Button>
            ) : (
              <Button
                testid="cycle-start"
                tone="go"
                why={first(lease, hasProgram, idle)}
                onClick={() =>
                  run('Cycle start', () => {
                    startingFrom(fromLine);
                    return command('/api/control/cycle-start', { from_line: fromLine });
                  })
                }
              >
                {fromLine > 0 ? `Start at line ${fromLine}` : 'Cycle start'}
              </Button>
            )}
            <Button testid="feed-hold" tone="warn" why={first(reason('operator'), running ? null : 'nothing runs')} onClick={() => run('Feed hold', () => command('/api/control/feed-hold'))}>
              Feed hold
            </Button>
            <Button testid="stop" tone="stop" why={first(lease, running || held ? null : 'nothing runs')} onClick={() => run('Stop', () => command('/api/control/stop'))}>
              Stop
            </Button>
          </div>
          <div class="toggles">
            <Toggle name="single-block" label="Single block" on={!!s?.single_block} why={lease} />
            <Toggle name="optional-stop" label="Opt. stop M1" on={!!s?.optional_stop} why={lease} />
            <Toggle name="block-delete" label="Block delete /" on={!!s?.block_delete} why={lease} />
          </div>
        </section>
        <Overrides />
        <SpindleCoolant />
        <Modal />
      </div>
    </div>
  );
}

function Toggle({ name, label, on, why }: { name: 'single-block' | 'optional-stop' | 'block-delete'; label: string; on: boolean; why: string | null }) {
  return (
    <Button testid={name} pressed={on} why={why} onClick={() => run(label, () => command(`/api/control/${name}`, { on: !on }))}>
      {label}: {on ? 'on' : 'off'}
    </Button>
  );
}

function Progress() {
  const s = status.value;
  const chain = loadedChain.value;
  const total = chain && chain.count > 0 ? chain.distance[chain.count - 1] : 0;
  const done = chain && chain.count > 0 ? chain.distance[Math.min(cursor.value.index, chain.count - 1)] : 0;
  const fraction = total > 0 ? done / total : 0;
  const elapsed = cycleStartedAt.value !== null && s ? s.time_s - cycleStartedAt.value : null;
  return (
    <section class="panel progress" aria-label="Progress">
      <div class="progress-bar" role="progressbar" aria-label="Path run" aria-valuemin={0} aria-valuemax={100} aria-valuenow={Math.round(fraction * 100)}>
        <div style={{ width: `${(fraction * 100).toFixed(1)}%` }} />
      </div>
      <dl class="facts">
        <dt>Path run</dt>
        <dd data-testid="progress">{percent(fraction)}</dd>
        <dt>Elapsed</dt>
        <dd>{duration(elapsed)}</dd>
        <dt>Cycle time (estimate)</dt>
        <dd data-testid="estimate">{estimateS.value === null ? '—' : duration(estimateS.value)}</dd>
        <dt>Path speed</dt>
        <dd data-testid="path-speed">{feed(s?.path_speed)} {s?.modal?.units === 'inch' ? 'in' : 'mm'}/min</dd>
      </dl>
    </section>
  );
}

function SpindleCoolant() {
  const s = status.value;
  const [rpm, setRpm] = useState(1000);
  const why = first(reason('lease'), whyNotIdle(s?.state));
  return (
    <section class="panel spindle" aria-label="Spindle and coolant">
      <h2>
        Spindle <span class="value">{Math.round(s?.spindle.rpm ?? 0)} rpm</span> <span class="dir">{s?.spindle.direction}</span>
      </h2>
      <div class="buttons">
        <label class="inline">
          rpm
          <input type="number" min={0} step={100} value={rpm} onInput={(e) => setRpm(Number(e.currentTarget.value))} />
        </label>
        <Button why={why} onClick={() => run('Spindle', () => command('/api/control/spindle', { direction: 'cw', rpm }))}>
          CW
        </Button>
        <Button why={why} onClick={() => run('Spindle', () => command('/api/control/spindle', { direction: 'ccw', rpm }))}>
          CCW
        </Button>
        <Button why={why} onClick={() => run('Spindle', () => command('/api/control/spindle', { direction: 'off' }))}>
          Off
        </Button>
      </div>
      <div class="buttons">
        <Button pressed={!!s?.mist} why={why} onClick={() => run('Coolant', () => command('/api/control/coolant', { mist: !s?.mist, flood: !!s?.flood }))}>
          Mist: {s?.mist ? 'on' : 'off'}
        </Button>
        <Button pressed={!!s?.flood} why={why} onClick={() => run('Coolant', () => command('/api/control/coolant', { mist: !!s?.mist, flood: !s?.flood }))}>
          Flood: {s?.flood ? 'on' : 'off'}
        </Button>
      </div>
    </section>
  );
}

function Modal() {
  const s = status.value;
  const m = s?.modal;
  return (
    <section class="panel modal-state" aria-label="Active codes">
      <h2>Active codes</h2>
      <p class="codes" data-testid="g-codes">
        {m ? m.g_codes.join(' ') : '—'}
      </p>
      <p class="codes">{m ? m.m_codes.join(' ') : '—'}</p>
      <dl class="facts">
        <dt>Tool</dt>
        <dd data-testid="tool">T{s?.tool ?? 0}</dd>
        <dt>F</dt>
        <dd>{m ? m.feed_rate : '—'}</dd>
        <dt>S</dt>
        <dd>{m ? m.speed : '—'}</dd>
        <dt>Work system</dt>
        <dd>{m?.work_system ?? '—'}</dd>
      </dl>
    </section>
  );
}
