import { readFileSync, readdirSync } from 'node:fs';
import { join } from 'node:path';
import { describe, expect, it } from 'vitest';
import { applyPatch } from '../src/api/socket';
import type { Status } from '../src/api/types';
import { tokenize } from '../src/gcode/highlight';
import { nextVersion, validName } from '../src/gcode/versions';
import { joinSections, splitSections } from '../src/state/toml';

const CONFIGS = join(__dirname, '..', '..', 'configs');

describe('the machine file by section', () => {
  it('puts every shipped machine file back together byte for byte', () => {
    for (const f of readdirSync(CONFIGS).filter((x) => x.endsWith('.toml'))) {
      const text = readFileSync(join(CONFIGS, f), 'utf8');
      expect(joinSections(splitSections(text))).toBe(text);
    }
  });

  it('groups the tables of one key and keeps a comment with the table it introduces', () => {
    const text = readFileSync(join(CONFIGS, 'sim-mill.toml'), 'utf8');
    const names = splitSections(text).map((s) => s.name);
    expect(names).toEqual(['', 'machine', 'axes', 'joints', 'tasks', 'fieldbus', 'spindle', 'io', 'plc', 'safety', 'files', 'handwheel']);
    const fieldbus = splitSections(text).find((s) => s.name === 'fieldbus')!;
    expect(fieldbus.text).toContain('# %IX0.0: the e-stop button');
    expect(fieldbus.text).toContain('[[fieldbus.devices]]');
    const sections = splitSections('# head\n\n[a]\nx = 1\n\n# about b\n[b]\ny = 2\n');
    expect(sections).toEqual([
      { name: '', text: '# head\n\n' },
      { name: 'a', text: '[a]\nx = 1\n\n' },
      { name: 'b', text: '# about b\n[b]\ny = 2\n' },
    ]);
  });
});

describe('G-code highlighting', () => {
  it('splits a line into words, comments, parameters and o-words', () => {
    const t = tokenize('N10 G1 X-1.5 Y2 F600 (cut) ; rest');
    expect(t.filter((x) => x.kind !== 'text').map((x) => [x.kind, x.text])).toEqual([
      ['lineno', 'N10'],
      ['g', 'G1'],
      ['axis', 'X-1.5'],
      ['axis', 'Y2'],
      ['feed', 'F600'],
      ['comment', '(cut)'],
      ['comment', '; rest'],
    ]);
    expect(tokenize('/G0 X#<depth>').map((x) => x.kind)).toEqual(['delete', 'g', 'text', 'axis', 'param']);
    expect(tokenize('o100 while [#1 lt 3]')[0]).toEqual({ kind: 'oword', text: 'o100 while' });
    // Every character is kept.
    const line = 'G2 X10 Y0 I5 J0 (arc (nested';
    expect(tokenize(line).map((x) => x.text).join('')).toBe(line);
  });
});

describe('save as a new version', () => {
  it('takes the next free version name and never an existing one', () => {
    expect(nextVersion('bracket.ngc', ['bracket.ngc'])).toBe('bracket-v2.ngc');
    expect(nextVersion('bracket.ngc', ['bracket.ngc', 'bracket-v2.ngc', 'bracket-v7.ngc'])).toBe('bracket-v8.ngc');
    expect(nextVersion('bracket-v3.ngc', ['bracket.ngc', 'bracket-v3.ngc'])).toBe('bracket-v4.ngc');
    expect(nextVersion('part', ['part'])).toBe('part-v2');
    expect(validName('bracket-v2.ngc')).toBe(true);
    expect(validName('../x.ngc')).toBe(false);
    expect(validName('.hidden')).toBe(false);
    expect(validName('a'.repeat(65))).toBe(false);
  });
});

describe('the live status', () => {
  it('takes a merge patch of top-level fields', () => {
    const s = { state: 'idle', line: 0, overrides: { feed: 1, rapid: 1, spindle: 1 } } as unknown as Status;
    const p = applyPatch(s, { state: 'running', overrides: { feed: 0.5, rapid: 1, spindle: 1 } });
    expect(p.state).toBe('running');
    expect(p.line).toBe(0);
    expect(p.overrides.feed).toBe(0.5);
    expect(s.state).toBe('idle');
  });
});
