import { signal } from '@preact/signals';
import { useEffect, useMemo, useRef, useState } from 'preact/hooks';
import { api, apiText } from '../../api/client';
import type { PathChain } from '../../api/preview';
import type { Estimate, ProgramCheck, ProgramError, ProgramInfo } from '../../api/types';
import { bytes, duration } from '../../format';
import { nextVersion, validName } from '../../gcode/versions';
import { first, whyNotIdle } from '../../state/permissions';
import { command, errorText, fetchChain, forgetChain, notify, reason, run, status } from '../../state/store';
import { Button, Why } from '../components/Button';
import { Editor } from '../components/Editor';
import { ProgramText } from '../components/ProgramText';
import { ToolPath } from '../components/ToolPath';

export const programs = signal<ProgramInfo[]>([]);

export async function refreshPrograms() {
  try {
    programs.value = await api<ProgramInfo[]>('/api/programs');
  } catch (e) {
    notify(`Programs: ${errorText(e)}`, 'error');
  }
}

function loadWhy(): string | null {
  const s = status.value;
  return first(reason('lease'), s?.mode === 'auto' ? whyNotIdle(s?.state) : null);
}

export async function loadProgram(name: string) {
  await run(`Load ${name}`, () => command('/api/control/program', { name }));
}

/** The program list in a select with Load (on the Operate screen). */
export function ProgramPicker() {
  const [name, setName] = useState('');
  useEffect(() => void refreshPrograms(), []);
  const list = programs.value;
  const chosen = name || status.value?.program || list[0]?.name || '';
  return (
    <div class="picker">
      <label class="inline">
        Program
        <select value={chosen} onChange={(e) => setName(e.currentTarget.value)} data-testid="program-select">
          {list.map((p) => (
            <option value={p.name}>{p.name}</option>
          ))}
        </select>
      </label>
      <Button testid="load-program" why={first(loadWhy(), chosen ? null : 'no program in the store')} onClick={() => loadProgram(chosen)}>
        Load
      </Button>
    </div>
  );
}

const CHECK_DELAY_MS = 350;
/**
 * Larger programs (CAM output) are shown read-only: a browser's text area lays out its
 * whole text, which takes seconds for a million lines. They are edited in a text editor
 * and uploaded again.
 */
export const EDIT_MAX_BYTES = 128 << 10;

export function Programs() {
  const [selected, setSelected] = useState<string | null>(null);
  const [text, setText] = useState('');
  const [saved, setSaved] = useState('');
  const [errors, setErrors] = useState<ProgramError[]>([]);
  const [checking, setChecking] = useState(false);
  const [chain, setChain] = useState<PathChain | null>(null);
  const [estimate, setEstimate] = useState<Estimate | null>(null);
  const [newName, setNewName] = useState('');
  const file = useRef<HTMLInputElement>(null);
  const checkTimer = useRef<ReturnType<typeof setTimeout> | null>(null);
  const checkSeq = useRef(0);
  useEffect(() => void refreshPrograms(), []);

  const open = async (name: string) => {
    setSelected(name);
    setEstimate(null);
    setErrors([]);
    try {
      // The preview and the text come in parallel; the preview is drawn when it is there.
      const text = apiText('/api/programs/{name}', { params: { name } });
      setChain(await fetchChain(name));
      const t = await text;
      setText(t);
      setSaved(t);
    } catch (e) {
      notify(`${name}: ${errorText(e)}`, 'error');
    }
  };

  const check = (t: string) => {
    if (checkTimer.current) clearTimeout(checkTimer.current);
    checkTimer.current = setTimeout(async () => {
      const seq = ++checkSeq.current;
      setChecking(true);
      try {
        const r = await api<ProgramCheck>('/api/programs/{name}/check', { method: 'POST', params: { name: selected ?? 'draft.ngc' }, text: t });
        if (seq === checkSeq.current) setErrors(r.errors);
      } catch (e) {
        if (seq === checkSeq.current) setErrors([{ line: 1, column: 0, code: 'hmi.check', message: errorText(e) }]);
      } finally {
        if (seq === checkSeq.current) setChecking(false);
      }
    }, CHECK_DELAY_MS);
  };

  const onText = (t: string) => {
    setText(t);
    check(t);
  };

  const save = async (name: string) => {
    if (!validName(name)) {
      notify(`${name}: a name has letters, digits, '.', '_' and '-' (at most 64)`, 'error');
      return;
    }
    try {
      await api('/api/programs/{name}', { method: 'PUT', params: { name }, text });
      forgetChain(name);
      notify(`Saved ${name}`);
      await refreshPrograms();
      await open(name);
    } catch (e) {
      const extra = (e as { problem?: { extra?: { errors?: ProgramError[] } } }).problem?.extra;
      if (extra?.errors) setErrors(extra.errors);
      notify(`Save ${name}: ${errorText(e)}`, 'error');
    }
  };

  const upload = async (f: File) => {
    const t = await f.text();
    const name = f.name.replace(/[^A-Za-z0-9._-]/g, '_').replace(/^\.+/, '');
    try {
      await api('/api/programs/{name}', { method: 'PUT', params: { name }, text: t });
      forgetChain(name);
      notify(`Uploaded ${name}`);
      await refreshPrograms();
      await open(name);
    } catch (e) {
      const extra = (e as { problem?: { extra?: { errors?: ProgramError[] } } }).problem?.extra;
      setSelected(name);
      setText(t);
      setSaved('');
      setErrors(extra?.errors ?? []);
      notify(`Upload ${name}: ${errorText(e)}`, 'error');
    }
  };

  const operator = reason('operator');
  const names = programs.value.map((p) => p.name);
  const version = selected ? nextVersion(selected, names) : null;
  const dirty = text !== saved;
  const large = text.length > EDIT_MAX_BYTES;
  const lines = useMemo(() => (large ? text.split('\n') : []), [text, large]);
  return (
    <div class="programs">
      <section class="panel list" aria-label="Program store">
        <h2>Programs</h2>
        <div class="buttons">
          <input
            ref={file}
            type="file"
            accept=".ngc,.nc,.tap,.gcode,.txt"
            class="hidden-file"
            data-testid="upload-input"
            aria-label="Program file to upload"
            onChange={(e) => {
              const f = e.currentTarget.files?.[0];
              if (f) void upload(f);
              e.currentTarget.value = '';
            }}
          />
          <Button testid="upload" tone="primary" why={operator} onClick={() => file.current?.click()}>
            Upload…
          </Button>
          <Button
            why={operator}
            onClick={() => {
              setSelected('new.ngc');
              setText('G21 G90 G17\n\nM2\n');
              setSaved('');
              setChain(null);
              check('G21 G90 G17\n\nM2\n');
            }}
          >
            New
          </Button>
        </div>
        <table class="table" data-testid="program-list">
          <thead>
            <tr>
              <th scope="col">Name</th>
              <th scope="col">Size</th>
              <th scope="col">Lines</th>
            </tr>
          </thead>
          <tbody>
            {programs.value.map((p) => (
              <tr key={p.name} class={p.name === selected ? 'selected' : ''}>
                <td>
                  <button type="button" class="link" onClick={() => void open(p.name)} data-testid={`open-${p.name}`}>
                    {p.name}
                  </button>
                </td>
                <td>{bytes(p.size)}</td>
                <td>{p.lines}</td>
              </tr>
            ))}
          </tbody>
        </table>
      </section>
      <section class="panel edit" aria-label="Editor">
        <h2>
          {selected ?? 'No program open'} {dirty && <em>(changed)</em>}
          <span class="check-state" data-testid="check-state">
            {checking ? 'checking…' : errors.length ? `${errors.length} error(s)` : selected ? 'no errors' : ''}
          </span>
        </h2>
        {selected && (
          <>
            {large ? (
              <>
                <ProgramText lines={lines} current={0} label={`G-code of ${selected} (read-only)`} />
                <p class="hint" data-testid="read-only">
                  {lines.length} lines, {bytes(text.length)}: too large to edit here (up to {bytes(EDIT_MAX_BYTES)}); edit it in a text editor and upload it again.
                </p>
              </>
            ) : (
              <Editor text={text} onText={onText} errors={errors} label={`G-code of ${selected}`} />
            )}
            <div class="buttons">
              <Button testid="save-version" tone="primary" why={first(operator, errors.length ? 'the program has errors' : null)} onClick={() => version && save(version)}>
                Save as {version}
              </Button>
              <label class="inline">
                Save as
                <input value={newName} placeholder="name.ngc" onInput={(e) => setNewName(e.currentTarget.value)} />
              </label>
              <Button why={first(operator, newName ? null : 'give a name', names.includes(newName) ? `${newName} exists: programs are not overwritten here` : null)} onClick={() => save(newName)}>
                Save
              </Button>
            </div>
          </>
        )}
      </section>
      <section class="panel preview" aria-label="Preview">
        <ToolPath chain={chain} label={`Preview of ${selected ?? 'nothing'}`} testid="preview-toolpath" />
        <div class="buttons">
          <Button
            testid="preview-load"
            tone="go"
            why={first(selected && !dirty && saved ? null : 'save the program first', loadWhy())}
            onClick={() => selected && loadProgram(selected)}
          >
            Load to run
          </Button>
          <Button
            why={selected && saved ? null : 'open a stored program'}
            onClick={async () => {
              if (!selected) return;
              setEstimate(null);
              const e = await run('Estimate', () => api<Estimate>('/api/programs/{name}/estimate', { params: { name: selected } }));
              if (e) setEstimate(e);
            }}
          >
            Estimate cycle time
          </Button>
          {estimate && (
            <span data-testid="program-estimate">
              {estimate.ended ? duration(estimate.cycle_time_s) : `does not end: ${estimate.faults.join(', ')}`}
            </span>
          )}
        </div>
        <Why why={chain?.errors.length ? `The preview stops at line ${chain.errors[0].line}: ${chain.errors[0].message}` : null} />
      </section>
    </div>
  );
}
