import { useEffect, useState } from 'preact/hooks';
import { api, getToken } from '../../api/client';
import type { TraceSample } from '../../api/socket';
import type { PlcVariableInfo, Timing } from '../../api/types';
import { machineTime } from '../../format';
import { first } from '../../state/permissions';
import { errorText, events, faults, info, link, notify, reason, refreshFaults, run, status } from '../../state/store';
import { Button, Why } from '../components/Button';
import { LivePlot } from '../components/LivePlot';

export function Diagnostics() {
  // The trace streams only while this screen is open.
  useEffect(() => {
    link.subscribe({ trace: true, trace_decimation: 5 });
    return () => link.subscribe({ trace: false });
  }, []);
  return (
    <div class="diagnostics">
      <div class="col">
        <Alarms />
        <History />
      </div>
      <div class="col">
        <Plots />
        <TaskTiming />
      </div>
      <div class="col">
        <PlcMonitor />
      </div>
    </div>
  );
}

function Alarms() {
  const list = faults.value;
  const open = list.filter((f) => !f.acknowledged);
  const why = reason('operator');
  const ack = (seq: number) =>
    run('Acknowledge', async () => {
      await api('/api/faults/acknowledge', { method: 'POST', json: { up_to_seq: seq } });
      await refreshFaults();
    });
  return (
    <section class="panel alarms" aria-label="Alarms">
      <h2>
        Alarms <span class={open.length ? 'badge' : 'badge quiet'}>{open.length}</span>
      </h2>
      <div class="buttons">
        <Button testid="ack-all" tone="primary" why={first(why, open.length ? null : 'no alarm to acknowledge')} onClick={() => ack(Math.max(...open.map((f) => f.seq)))}>
          Acknowledge all
        </Button>
      </div>
      <table class="table" data-testid="alarm-list">
        <thead>
          <tr>
            <th scope="col">Time</th>
            <th scope="col">Alarm</th>
            <th scope="col">State</th>
          </tr>
        </thead>
        <tbody>
          {[...list].reverse().map((f) => (
            <tr key={f.seq} class={f.acknowledged ? 'acked' : 'open'} data-seq={f.seq}>
              <td class="nowrap">{machineTime(f.time_s)}</td>
              <td class="alarm-text">
                {f.message}
                {f.line ? ` (line ${f.line})` : ''}
                {f.joint ? ` [${f.joint}]` : ''}
                <br />
                <code>{f.code}</code>
              </td>
              <td class="nowrap">
                {f.acknowledged ? (
                  'acknowledged'
                ) : (
                  <Button why={why} class="small" onClick={() => ack(f.seq)} testid={`ack-${f.seq}`}>
                    Acknowledge
                  </Button>
                )}
              </td>
            </tr>
          ))}
        </tbody>
      </table>
    </section>
  );
}

function History() {
  const [kinds, setKinds] = useState<'messages' | 'all'>('messages');
  const list = events.value.filter((e) => (kinds === 'all' ? e.kind !== 'ack' : ['message', 'fault', 'program_end', 'client_lost', 'machine_lost'].includes(e.kind)));
  return (
    <section class="panel history" aria-label="Messages and history">
      <h2>Messages and history</h2>
      <div class="choice" role="group" aria-label="Show">
        <Button pressed={kinds === 'messages'} onClick={() => setKinds('messages')}>
          Messages and alarms
        </Button>
        <Button pressed={kinds === 'all'} onClick={() => setKinds('all')}>
          Everything
        </Button>
      </div>
      <ol class="event-list" data-testid="event-list">
        {[...list].reverse().slice(0, 200).map((e) => (
          <li key={e.seq} class={`ev ev-${e.kind}`}>
            <span class="t">{machineTime(e.time_s)}</span> <span class="k">{e.kind}</span> {e.message}
            {e.line ? ` (line ${e.line})` : ''}
          </li>
        ))}
      </ol>
    </section>
  );
}

function Plots() {
  const joints = status.value?.joints.map((j) => j.name) ?? [];
  const velocity = (s: TraceSample, p: TraceSample | null) => {
    if (!p || s.time_s <= p.time_s) return null;
    const dt = s.time_s - p.time_s;
    return s.setpoint.map((v, i) => (v - p.setpoint[i]) / dt);
  };
  const download = async () => {
    try {
      const r = await fetch('/api/diagnostics/trace', { headers: { Authorization: `Bearer ${getToken()}` } });
      if (!r.ok) throw new Error(`${r.status} ${r.statusText}`);
      const url = URL.createObjectURL(await r.blob());
      const a = document.createElement('a');
      a.href = url;
      a.download = `rtcnc-trace-${new Date().toISOString().replace(/[:.]/g, '-')}.json`;
      a.click();
      setTimeout(() => URL.revokeObjectURL(url), 10_000);
    } catch (e) {
      notify(`Trace: ${errorText(e)}`, 'error');
    }
  };
  return (
    <section class="panel plots" aria-label="Live plots">
      <h2>Live plots</h2>
      <LivePlot title="Velocity per joint (set-point)" unit="units/s" series={joints} pick={velocity} testid="plot-velocity" />
      <LivePlot title="Following error per joint" unit="µm (mm × 1000)" series={joints} pick={(s) => s.following_error.map((e) => e * 1000)} testid="plot-ferror" />
      <div class="buttons">
        <Button testid="trace-download" onClick={() => void download()}>
          Download the last 10 s (Perfetto JSON)
        </Button>
      </div>
    </section>
  );
}

function TaskTiming() {
  const [t, setT] = useState<Timing | null>(null);
  const [error, setError] = useState<string | null>(null);
  useEffect(() => {
    const poll = () =>
      api<Timing>('/api/diagnostics/timing').then(
        (x) => {
          setT(x);
          setError(null);
        },
        (e) => setError(errorText(e)),
      );
    void poll();
    const id = setInterval(poll, 1000);
    return () => clearInterval(id);
  }, []);
  const us = (v: number) => v.toFixed(1);
  return (
    <section class="panel timing" aria-label="Task timing">
      <h2>Task timing</h2>
      <Why why={error} />
      {t && (
        <p class="hint">
          {t.fifo ? 'Real-time threads (SCHED_FIFO).' : 'Normal threads: no SCHED_FIFO permission, timing is best effort.'} Set-point underruns: {t.underruns}.
        </p>
      )}
      <table class="table numbers" data-testid="timing">
        <thead>
          <tr>
            <th scope="col">Task</th>
            <th scope="col">Runs</th>
            <th scope="col">Exec mean µs</th>
            <th scope="col">p99 µs</th>
            <th scope="col">max µs</th>
            <th scope="col">Late p99 µs</th>
            <th scope="col">Late max µs</th>
            <th scope="col">Misses</th>
          </tr>
        </thead>
        <tbody>
          {t?.tasks.map((x) => (
            <tr key={x.name} class={x.deadline_misses ? 'warn' : ''}>
              <th scope="row">{x.name}</th>
              <td>{x.activations}</td>
              <td>{us(x.execution_mean_us)}</td>
              <td>{us(x.execution_p99_us)}</td>
              <td>{us(x.execution_max_us)}</td>
              <td>{us(x.lateness_p99_us)}</td>
              <td>{us(x.lateness_max_us)}</td>
              <td>{x.deadline_misses}</td>
            </tr>
          ))}
        </tbody>
      </table>
    </section>
  );
}

function PlcMonitor() {
  const [vars, setVars] = useState<PlcVariableInfo[]>([]);
  const [filter, setFilter] = useState('');
  const [watch, setWatch] = useState<string[]>([]);
  const [values, setValues] = useState<Record<string, string>>({});
  const [error, setError] = useState<string | null>(null);
  useEffect(() => {
    api<PlcVariableInfo[]>('/api/plc/variables').then(setVars, (e) => setError(errorText(e)));
    const w = status.value?.plc_watch.map((x) => x.path) ?? [];
    setWatch(w);
  }, []);
  const live = new Map(status.value?.plc_watch.map((w) => [w.path, w]) ?? []);
  const canWatch = reason('operator');
  const canForce = reason('setter');
  const setList = (paths: string[]) =>
    run('Watch', async () => {
      await api('/api/plc/watch', { method: 'PUT', json: { paths } });
      setWatch(paths);
    });
  const shown = vars.filter((v) => v.path.toLowerCase().includes(filter.toLowerCase())).slice(0, 200);
  return (
    <section class="panel plc" aria-label="PLC signals">
      <h2>PLC signals</h2>
      <Why why={error} />
      <h3>Watched ({watch.length} of 16)</h3>
      <table class="table" data-testid="plc-watch">
        <thead>
          <tr>
            <th scope="col">Variable</th>
            <th scope="col">Value</th>
            <th scope="col">Force</th>
          </tr>
        </thead>
        <tbody>
          {watch.map((p) => {
            const w = live.get(p);
            return (
              <tr key={p} class={w?.forced ? 'forced' : ''}>
                <th scope="row">
                  {p}
                  <Button label={`Stop watching ${p}`} class="small" why={canWatch} onClick={() => setList(watch.filter((x) => x !== p))}>
                    ✕
                  </Button>
                </th>
                <td data-testid={`plc-value-${p}`}>
                  {w ? w.value : '—'}
                  {w?.forced ? ' (forced)' : ''}
                </td>
                <td class="force">
                  <input aria-label={`Force value of ${p}`} value={values[p] ?? ''} placeholder="TRUE, 42, T#1s" disabled={!!canForce} onInput={(e) => setValues({ ...values, [p]: e.currentTarget.value })} />
                  <Button class="small" why={first(canForce, values[p] ? null : 'give a value')} onClick={() => run(`Force ${p}`, () => api('/api/plc/force', { method: 'POST', json: { path: p, value: values[p] } }))}>
                    Force
                  </Button>
                  <Button class="small" why={first(canForce, w?.forced ? null : 'not forced')} onClick={() => run(`Release ${p}`, () => api('/api/plc/force/{path}', { method: 'DELETE', params: { path: p } }))}>
                    Release
                  </Button>
                </td>
              </tr>
            );
          })}
        </tbody>
      </table>
      <Why why={canForce ? `Forcing: ${canForce}` : null} />
      <h3>Variables</h3>
      <label class="inline wide">
        Find
        <input value={filter} onInput={(e) => setFilter(e.currentTarget.value)} placeholder="door, spindle, …" />
      </label>
      <ul class="plc-vars">
        {shown.map((v) => (
          <li key={v.path}>
            <Button
              why={first(canWatch, watch.includes(v.path) ? 'watched' : null, watch.length >= 16 ? 'at most 16 are watched' : null)}
              label={`Watch ${v.path}`}
              onClick={() => setList([...watch, v.path])}
            >
              Watch
            </Button>
            <span class="mono">{v.path}</span> <em>{v.type_name}</em> {v.location && <code>{v.location}</code>}
          </li>
        ))}
      </ul>
      <p class="hint">{info.value ? `${vars.length} variables; the first 200 that match are listed.` : ''}</p>
    </section>
  );
}
