// "Save as a new version": a program is never overwritten from the editor; its next
// version gets the next free name `NAME-vN.EXT`.

const VERSION = /^(.*?)-v(\d+)$/;

function split(name: string): [stem: string, ext: string] {
  const dot = name.lastIndexOf('.');
  return dot > 0 ? [name.slice(0, dot), name.slice(dot)] : [name, ''];
}

/** The next free version name of `name` among `existing`. */
export function nextVersion(name: string, existing: string[]): string {
  const [stem, ext] = split(name);
  const base = VERSION.exec(stem)?.[1] ?? stem;
  const taken = new Set(existing);
  let highest = 1;
  for (const other of existing) {
    const [s, e] = split(other);
    const m = VERSION.exec(s);
    if (e === ext && m && m[1] === base) highest = Math.max(highest, Number(m[2]));
  }
  let n = highest + 1;
  while (taken.has(`${base}-v${n}${ext}`)) n++;
  return `${base}-v${n}${ext}`;
}

/** Whether a name is one the API stores (letters, digits, '.', '_', '-', at most 64). */
export function validName(name: string): boolean {
  return /^[A-Za-z0-9_\-][A-Za-z0-9._\-]{0,63}$/.test(name);
}
