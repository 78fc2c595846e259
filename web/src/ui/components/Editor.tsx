// A G-code editor: a plain textarea (so typing, selection and the touch keyboard work as
// everywhere) over the same text highlighted, of which only the lines in sight are drawn;
// the interpreter's errors are marked at their lines.
import { useEffect, useRef, useState } from 'preact/hooks';
import type { ProgramError } from '../../api/types';
import { Highlighted } from './ProgramText';

const ROW = 22;

interface Props {
  text: string;
  onText: (t: string) => void;
  errors: ProgramError[];
  label: string;
}

export function Editor({ text, onText, errors, label }: Props) {
  const area = useRef<HTMLTextAreaElement>(null);
  const [scroll, setScroll] = useState({ top: 0, left: 0 });
  const [height, setHeight] = useState(400);
  useEffect(() => {
    const el = area.current!;
    const ro = new ResizeObserver(() => setHeight(el.clientHeight));
    ro.observe(el);
    return () => ro.disconnect();
  }, []);
  const lines = text.split('\n');
  const byLine = new Map<number, ProgramError[]>();
  for (const e of errors) byLine.set(e.line, [...(byLine.get(e.line) ?? []), e]);
  const first = Math.max(0, Math.floor(scroll.top / ROW) - 2);
  const last = Math.min(lines.length, Math.ceil((scroll.top + height) / ROW) + 2);
  const rows = [];
  for (let i = first; i < last; i++) {
    const errs = byLine.get(i + 1);
    rows.push(
      <div key={i} class={`eline${errs ? ' has-error' : ''}`} style={{ top: `${i * ROW - scroll.top}px` }}>
        <span class="lineno">{i + 1}</span>
        <span class="code" style={{ transform: `translateX(${-scroll.left}px)` }}>
          <Highlighted text={lines[i]} />
          {errs && (
            <span class="error-mark" role="note">
              {'  ◀ '}
              {errs.map((e) => `col ${e.column}: ${e.message}`).join('; ')}
            </span>
          )}
        </span>
      </div>,
    );
  }
  const goTo = (line: number) => {
    const el = area.current!;
    let at = 0;
    for (let i = 0; i < line - 1 && i < lines.length; i++) at += lines[i].length + 1;
    el.focus();
    el.setSelectionRange(at, at + (lines[line - 1]?.length ?? 0));
    el.scrollTop = Math.max(0, (line - 4) * ROW);
  };
  return (
    <div class="editor-wrap">
      <div class="editor">
        <div class="editor-view" aria-hidden="true">
          {rows}
        </div>
        <textarea
          ref={area}
          value={text}
          spellcheck={false}
          wrap="off"
          aria-label={label}
          data-testid="editor"
          onInput={(e) => onText(e.currentTarget.value)}
          onScroll={(e) => setScroll({ top: e.currentTarget.scrollTop, left: e.currentTarget.scrollLeft })}
        />
      </div>
      <ul class="errors" aria-label="Errors" data-testid="editor-errors">
        {errors.map((e) => (
          <li key={`${e.line}:${e.column}`}>
            <button type="button" class="link" onClick={() => goTo(e.line)}>
              line {e.line}, column {e.column}
            </button>
            : {e.message} <code>{e.code}</code>
          </li>
        ))}
      </ul>
    </div>
  );
}
