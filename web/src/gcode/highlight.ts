// G-code tokens for highlighting: words (letter and number), comments, parameters,
// o-word control flow, block delete, line numbers. The interpreter on the server is the
// judge of errors; this only colours.

export type TokenKind = 'g' | 'm' | 'axis' | 'feed' | 'tool' | 'word' | 'comment' | 'param' | 'oword' | 'number' | 'delete' | 'lineno' | 'text';

export interface Token {
  kind: TokenKind;
  text: string;
}

const AXES = 'XYZABCUVWIJKR';

export function tokenize(line: string): Token[] {
  const out: Token[] = [];
  let i = 0;
  const push = (kind: TokenKind, text: string) => {
    const last = out[out.length - 1];
    if (last && last.kind === kind && kind === 'text') last.text += text;
    else out.push({ kind, text });
  };
  while (i < line.length) {
    const c = line[i];
    if (c === '(') {
      const end = line.indexOf(')', i);
      const j = end < 0 ? line.length : end + 1;
      push('comment', line.slice(i, j));
      i = j;
    } else if (c === ';') {
      push('comment', line.slice(i));
      i = line.length;
    } else if (c === '/' && line.slice(0, i).trim() === '') {
      push('delete', c);
      i++;
    } else if (c === '#') {
      const m = /^#(<[^>]*>|\d+)?/.exec(line.slice(i))!;
      push('param', m[0]);
      i += m[0].length;
    } else if ((c === 'o' || c === 'O') && /^[oO](<[^>]*>|\d+)/.test(line.slice(i))) {
      const m = /^[oO](<[^>]*>|\d+)\s*[a-zA-Z]*/.exec(line.slice(i))!;
      push('oword', m[0]);
      i += m[0].length;
    } else if (/[a-zA-Z]/.test(c)) {
      const m = /^[a-zA-Z]\s*[-+]?\s*(\d+\.?\d*|\.\d+)?/.exec(line.slice(i))!;
      const letter = c.toUpperCase();
      const kind: TokenKind =
        letter === 'G' ? 'g' : letter === 'M' ? 'm' : letter === 'N' ? 'lineno' : AXES.includes(letter) ? 'axis' : letter === 'F' || letter === 'S' ? 'feed' : letter === 'T' || letter === 'H' || letter === 'D' ? 'tool' : 'word';
      push(kind, m[0]);
      i += Math.max(m[0].length, 1);
    } else if (/[\d.+-]/.test(c)) {
      const m = /^[-+]?(\d+\.?\d*|\.\d+)/.exec(line.slice(i));
      if (m) {
        push('number', m[0]);
        i += m[0].length;
      } else {
        push('text', c);
        i++;
      }
    } else {
      push('text', c);
      i++;
    }
  }
  return out;
}
