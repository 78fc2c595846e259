// A program's text, only the lines in sight drawn (a CAM program has a million), with the
// executing line highlighted and kept in sight, and a line chosen by a tap.
import { useEffect, useRef, useState } from 'preact/hooks';
import { tokenize } from '../../gcode/highlight';

const ROW = 24;

interface Props {
  lines: string[];
  /** 1-based executing line, 0 for none. */
  current: number;
  /** 1-based chosen line (run from line), 0 for none. */
  chosen?: number;
  onChoose?: (line: number) => void;
  /** Lines with errors: line -> message. */
  errors?: Map<number, string>;
  label: string;
}

export function Highlighted({ text }: { text: string }) {
  return (
    <>
      {tokenize(text).map((t, i) => (t.kind === 'text' ? t.text : <span key={i} class={`tk-${t.kind}`}>{t.text}</span>))}
    </>
  );
}

export function ProgramText({ lines, current, chosen = 0, onChoose, errors, label }: Props) {
  const box = useRef<HTMLDivElement>(null);
  const [top, setTop] = useState(0);
  const [height, setHeight] = useState(400);
  useEffect(() => {
    const el = box.current!;
    const ro = new ResizeObserver(() => setHeight(el.clientHeight));
    ro.observe(el);
    return () => ro.disconnect();
  }, []);
  // Keep the executing line in sight, a few lines from the top.
  useEffect(() => {
    const el = box.current;
    if (!el || current <= 0) return;
    const y = (current - 1) * ROW;
    if (y < el.scrollTop || y > el.scrollTop + el.clientHeight - 3 * ROW) {
      el.scrollTop = Math.max(0, y - 3 * ROW);
    }
  }, [current]);
  const first = Math.max(0, Math.floor(top / ROW) - 5);
  const last = Math.min(lines.length, Math.ceil((top + height) / ROW) + 5);
  const rows = [];
  for (let i = first; i < last; i++) {
    const n = i + 1;
    const err = errors?.get(n);
    rows.push(
      <div
        key={n}
        class={`line${n === current ? ' current' : ''}${n === chosen ? ' chosen' : ''}${err ? ' has-error' : ''}`}
        style={{ top: `${i * ROW}px` }}
        data-line={n}
        aria-current={n === current ? 'step' : undefined}
        title={err}
        onClick={onChoose ? () => onChoose(n) : undefined}
      >
        <span class="lineno">{n}</span>
        <span class="code">
          <Highlighted text={lines[i]} />
        </span>
      </div>,
    );
  }
  return (
    <div
      class="program-text"
      ref={box}
      tabIndex={0}
      role="region"
      aria-label={label}
      data-testid="program-text"
      data-current={current}
      onScroll={(e) => setTop(e.currentTarget.scrollTop)}
    >
      <div class="program-rows" style={{ height: `${lines.length * ROW}px` }}>
        {rows}
      </div>
    </div>
  );
}
