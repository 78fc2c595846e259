// How numbers, times and states read on the panel.

/** A position in program units: 3 decimals in mm, 4 in inches, a real minus sign, never "-0". */
export function position(v: number | undefined | null, units: string = 'mm'): string {
  if (v === undefined || v === null || !Number.isFinite(v)) return '—';
  const digits = units === 'inch' ? 4 : 3;
  let s = v.toFixed(digits);
  if (/^-0\.?0*$/.test(s)) s = s.slice(1);
  return s.replace('-', '−');
}

/** A factor as a percentage: 1 -> "100 %". */
export function percent(f: number | undefined | null): string {
  if (f === undefined || f === null || !Number.isFinite(f)) return '—';
  return `${Math.round(f * 100)} %`;
}

/** Seconds as h:mm:ss or m:ss. */
export function duration(s: number | undefined | null): string {
  if (s === undefined || s === null || !Number.isFinite(s) || s < 0) return '—';
  const t = Math.round(s);
  const h = Math.floor(t / 3600);
  const m = Math.floor((t % 3600) / 60);
  const sec = t % 60;
  const mm = h > 0 ? String(m).padStart(2, '0') : String(m);
  return (h > 0 ? `${h}:` : '') + `${mm}:${String(sec).padStart(2, '0')}`;
}

/** Bytes as B, KiB, MiB. */
export function bytes(n: number): string {
  if (n < 1024) return `${n} B`;
  if (n < 1024 * 1024) return `${(n / 1024).toFixed(1)} KiB`;
  return `${(n / 1024 / 1024).toFixed(1)} MiB`;
}

const STATES: Record<string, string> = {
  starting: 'Starting',
  estop: 'E-stop',
  idle: 'Idle',
  running: 'Running',
  held: 'Feed hold',
  paused: 'Paused',
  waiting_for_logic: 'Waiting for logic',
  fault: 'Fault',
  unknown: 'Unknown',
};

/** A machine state for a person. */
export function stateLabel(state: string | undefined): string {
  return STATES[state ?? 'unknown'] ?? state ?? 'Unknown';
}

/** The colour class of a state: ok, busy, warn, alarm. */
export function stateTone(state: string | undefined): 'ok' | 'busy' | 'warn' | 'alarm' {
  switch (state) {
    case 'idle':
      return 'ok';
    case 'running':
    case 'waiting_for_logic':
    case 'starting':
      return 'busy';
    case 'held':
    case 'paused':
      return 'warn';
    default:
      return 'alarm';
  }
}

/** Machine time as a clock of the machine's day: seconds since its start, to 0.1 s. */
export function machineTime(s: number): string {
  return `${duration(Math.floor(s))}.${Math.floor((s % 1) * 10)}`;
}

/** Speed in units/s as units/min (how feeds are written in programs). */
export function feed(unitsPerS: number | undefined | null): string {
  if (unitsPerS === undefined || unitsPerS === null || !Number.isFinite(unitsPerS)) return '—';
  return String(Math.round(unitsPerS * 60));
}

/** A plot's tick label: three significant digits, exponents outside 0.01..1000, never "-0". */
export function axisNumber(v: number): string {
  if (v === 0) return '0';
  const a = Math.abs(v);
  const s = a >= 1000 || a < 0.01 ? v.toExponential(1) : v.toPrecision(3).replace(/(\.\d*?)0+$/, '$1').replace(/\.$/, '');
  return s.replace('-', '−');
}
