import { useEffect, useState } from 'preact/hooks';
import { api } from '../../api/client';
import type { MachineFile, MachineFileSaved, Tool, WorkOffset } from '../../api/types';
import { first } from '../../state/permissions';
import { type Section, joinSections, splitSections } from '../../state/toml';
import { errorText, info, notify, reason, run } from '../../state/store';
import { Button, Why } from '../components/Button';

export function Setup() {
  return (
    <div class="setup">
      <div class="col">
        <Tools />
        <Offsets />
      </div>
      <div class="col">
        <MachineFileEditor />
      </div>
    </div>
  );
}

function num(v: string): number {
  const n = Number(v);
  return Number.isFinite(n) ? n : NaN;
}

function Tools() {
  const [tools, setTools] = useState<Tool[]>([]);
  const [error, setError] = useState<string | null>(null);
  const load = () =>
    api<Tool[]>('/api/setup/tools').then(
      (t) => {
        setTools(t);
        setError(null);
      },
      (e) => setError(errorText(e)),
    );
  useEffect(() => void load(), []);
  const why = reason('setter');
  const set = (i: number, change: Partial<Tool>) => setTools(tools.map((t, k) => (k === i ? { ...t, ...change } : t)));
  const invalid = tools.some((t) => !Number.isFinite(t.diameter) || !Number.isFinite(t.offset.Z ?? 0) || t.number < 0 || t.pocket < 0);
  return (
    <section class="panel" aria-label="Tool table">
      <h2>Tool table</h2>
      <Why why={error} />
      <table class="table editable" data-testid="tool-table">
        <thead>
          <tr>
            <th scope="col">T</th>
            <th scope="col">Pocket</th>
            <th scope="col">Length Z (mm)</th>
            <th scope="col">Diameter (mm)</th>
            <th scope="col">Comment</th>
            <th scope="col">
              <span class="sr-only">Remove</span>
            </th>
          </tr>
        </thead>
        <tbody>
          {tools.map((t, i) => (
            <tr key={i}>
              <td>
                <input aria-label={`Tool ${t.number} number`} type="number" value={t.number} disabled={!!why} onInput={(e) => set(i, { number: Math.trunc(num(e.currentTarget.value)) })} />
              </td>
              <td>
                <input aria-label={`Tool ${t.number} pocket`} type="number" value={t.pocket} disabled={!!why} onInput={(e) => set(i, { pocket: Math.trunc(num(e.currentTarget.value)) })} />
              </td>
              <td>
                <input aria-label={`Tool ${t.number} length`} type="number" step="any" value={t.offset.Z ?? 0} disabled={!!why} onInput={(e) => set(i, { offset: { ...t.offset, Z: num(e.currentTarget.value) } })} />
              </td>
              <td>
                <input aria-label={`Tool ${t.number} diameter`} type="number" step="any" value={t.diameter} disabled={!!why} onInput={(e) => set(i, { diameter: num(e.currentTarget.value) })} />
              </td>
              <td>
                <input aria-label={`Tool ${t.number} comment`} value={t.comment ?? ''} disabled={!!why} onInput={(e) => set(i, { comment: e.currentTarget.value })} />
              </td>
              <td>
                <Button why={why} label={`Remove tool ${t.number}`} onClick={() => setTools(tools.filter((_, k) => k !== i))}>
                  ✕
                </Button>
              </td>
            </tr>
          ))}
        </tbody>
      </table>
      <div class="buttons">
        <Button
          why={why}
          onClick={() => {
            const n = Math.max(0, ...tools.map((t) => t.number)) + 1;
            setTools([...tools, { number: n, pocket: n, offset: { Z: 0 }, diameter: 0, comment: '' }]);
          }}
        >
          Add tool
        </Button>
        <Button
          testid="tools-save"
          tone="primary"
          why={first(why, invalid ? 'a value is not a number' : null)}
          onClick={() =>
            run('Tool table', async () => {
              await api('/api/setup/tools', { method: 'PUT', json: tools });
              notify('Tool table saved; the machine has read it');
              await load();
            })
          }
        >
          Save tool table
        </Button>
        <Button onClick={() => void load()}>Reload</Button>
      </div>
      <Why why={why} />
    </section>
  );
}

function Offsets() {
  const [offsets, setOffsets] = useState<WorkOffset[]>([]);
  const axes = info.value?.axes ?? [];
  const load = () => api<WorkOffset[]>('/api/setup/offsets').then(setOffsets, (e) => notify(`Offsets: ${errorText(e)}`, 'error'));
  useEffect(() => void load(), []);
  const why = reason('setter');
  const set = (i: number, o: WorkOffset) => setOffsets(offsets.map((x, k) => (k === i ? o : x)));
  return (
    <section class="panel" aria-label="Work offsets">
      <h2>Work offsets</h2>
      <table class="table editable" data-testid="offsets">
        <thead>
          <tr>
            <th scope="col">System</th>
            {axes.map((a) => (
              <th scope="col">{a} ({'ABC'.includes(a) ? '°' : 'mm'})</th>
            ))}
            <th scope="col">Rotation (°)</th>
            <th scope="col">
              <span class="sr-only">Save</span>
            </th>
          </tr>
        </thead>
        <tbody>
          {offsets.map((o, i) => (
            <tr key={o.system}>
              <th scope="row">{o.system}</th>
              {axes.map((a) => (
                <td>
                  <input aria-label={`${o.system} ${a}`} type="number" step="any" value={o.offset[a] ?? 0} disabled={!!why} onInput={(e) => set(i, { ...o, offset: { ...o.offset, [a]: num(e.currentTarget.value) } })} />
                </td>
              ))}
              <td>
                <input aria-label={`${o.system} rotation`} type="number" step="any" value={o.rotation ?? 0} disabled={!!why} onInput={(e) => set(i, { ...o, rotation: num(e.currentTarget.value) })} />
              </td>
              <td>
                <Button
                  why={first(why, Object.values(o.offset).every(Number.isFinite) ? null : 'a value is not a number')}
                  onClick={() =>
                    run(`${o.system}`, async () => {
                      await api(`/api/setup/offsets/{system}`, { method: 'PUT', params: { system: o.system }, json: o });
                      notify(`${o.system} saved`);
                      await load();
                    })
                  }
                >
                  Save
                </Button>
              </td>
            </tr>
          ))}
        </tbody>
      </table>
      <Why why={why ?? 'The machine must be idle: an offset is written through an MDI G10 line.'} />
    </section>
  );
}

function MachineFileEditor() {
  const [file, setFile] = useState<MachineFile | null>(null);
  const [sections, setSections] = useState<Section[]>([]);
  const [error, setError] = useState<string | null>(null);
  const load = () =>
    api<MachineFile>('/api/setup/machine').then(
      (f) => {
        setFile(f);
        setSections(splitSections(f.text));
      },
      (e) => setError(errorText(e)),
    );
  useEffect(() => void load(), []);
  const why = reason('admin');
  const changed = file ? joinSections(sections) !== file.text : false;
  return (
    <section class="panel machine-file" aria-label="Machine file">
      <h2>Machine file</h2>
      {file && (
        <p class="hint">
          {file.path}
          {file.changed_since_start && <strong data-testid="machine-file-pending"> — changed since the start: the machine takes it at its next start</strong>}
        </p>
      )}
      <Why why={error} />
      {sections.map((s, i) => (
        <details key={i} open={i < 1}>
          <summary>{s.name ? `[${s.name}]` : 'header'}</summary>
          <textarea
            class="mono"
            aria-label={`Section ${s.name || 'header'}`}
            value={s.text}
            readOnly={!!why}
            rows={Math.min(24, s.text.split('\n').length + 1)}
            spellcheck={false}
            onInput={(e) => setSections(sections.map((x, k) => (k === i ? { ...x, text: e.currentTarget.value } : x)))}
          />
        </details>
      ))}
      <div class="buttons">
        <Button
          testid="machine-save"
          tone="primary"
          why={first(why, changed ? null : 'nothing changed')}
          onClick={async () => {
            setError(null);
            try {
              await api<MachineFileSaved>('/api/setup/machine', { method: 'PUT', text: joinSections(sections) });
              notify('Machine file saved: it applies at the next start of the machine');
              await load();
            } catch (e) {
              setError(errorText(e));
            }
          }}
        >
          Check and save
        </Button>
        <Button onClick={() => void load()}>Revert</Button>
      </div>
      <Why why={why ? `Read only: ${why}` : 'Saved only when the machine would start with it (the same checks as at its start); it applies at the next start.'} />
    </section>
  );
}
