// The machine file by section: its TOML text cut at the top-level tables (`[axes.x]` and
// `[axes.y]` both belong to `axes`, every `[[joints]]` to `joints`), comments kept with the
// section they stand right before, so that the sections put back together are the file again.

export interface Section {
  /** Top-level key (`machine`, `axes`, `joints`, …); '' for what comes before any table. */
  name: string;
  text: string;
}

const HEADER = /^\s*\[\[?\s*([A-Za-z0-9_\-"]+)/;

export function splitSections(text: string): Section[] {
  const lines = text.split('\n');
  const sections: Section[] = [{ name: '', text: '' }];
  let pending: string[] = [];
  const flush = (into: Section) => {
    if (pending.length) into.text += pending.join('\n') + '\n';
    pending = [];
  };
  for (let i = 0; i < lines.length; i++) {
    const line = lines[i];
    const last = i === lines.length - 1;
    const m = HEADER.exec(line);
    const current = sections[sections.length - 1];
    if (m) {
      const name = m[1].replace(/"/g, '');
      // Comment lines right before a header (no blank line between) introduce it.
      let k = pending.length;
      while (k > 0 && pending[k - 1].trim().startsWith('#')) k--;
      const intro = pending.slice(k);
      pending = pending.slice(0, k);
      flush(current);
      if (name === current.name) {
        current.text += [...intro, line].join('\n') + '\n';
      } else {
        sections.push({ name, text: [...intro, line].join('\n') + '\n' });
      }
    } else if (last) {
      pending.push(line);
      current.text += pending.join('\n');
      pending = [];
    } else {
      pending.push(line);
    }
  }
  if (pending.length) sections[sections.length - 1].text += pending.join('\n');
  return sections.filter((s, i) => i > 0 || s.text !== '');
}

export function joinSections(sections: Section[]): string {
  return sections.map((s) => s.text).join('');
}
