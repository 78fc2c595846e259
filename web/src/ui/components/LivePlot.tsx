// A live plot (uPlot) of the trace the machine streams: a window of the last seconds,
// redrawn a few times a second.
import { useEffect, useRef } from 'preact/hooks';
import uPlot from 'uplot';
import 'uplot/dist/uPlot.min.css';
import type { TraceSample } from '../../api/socket';
import { axisNumber } from '../../format';
import { traceListeners } from '../../state/store';

const PALETTE = ['#4fc3f7', '#ffb74d', '#81c784', '#f06292', '#ba68c8', '#fff176', '#90a4ae', '#e57373', '#64b5f6'];

interface Props {
  title: string;
  unit: string;
  series: string[];
  /** Values of one sample per series; `prev` is the sample before (for derivatives). */
  pick: (s: TraceSample, prev: TraceSample | null) => number[] | null;
  seconds?: number;
  testid?: string;
}

export function LivePlot({ title, unit, series, pick, seconds = 10, testid }: Props) {
  const box = useRef<HTMLDivElement>(null);
  useEffect(() => {
    const el = box.current!;
    const xs: number[] = [];
    const ys: number[][] = series.map(() => []);
    let prev: TraceSample | null = null;
    const plot = new uPlot(
      {
        width: el.clientWidth || 400,
        height: 190,
        title,
        scales: { x: { time: false } },
        axes: [
          { stroke: '#c9d1d9', grid: { stroke: '#2b333d' }, ticks: { stroke: '#2b333d' }, label: 'machine time (s)' },
          {
            stroke: '#c9d1d9',
            grid: { stroke: '#2b333d' },
            ticks: { stroke: '#2b333d' },
            label: unit,
            size: 70,
            values: (_u: uPlot, ticks: number[]) => ticks.map((t) => axisNumber(t)),
          },
        ],
        series: [{ label: 't' }, ...series.map((s, i) => ({ label: s, stroke: PALETTE[i % PALETTE.length], width: 1.5 }))],
        legend: { show: true },
      },
      [xs, ...ys],
      el,
    );
    let dirty = false;
    const onSamples = (samples: TraceSample[]) => {
      for (const s of samples) {
        const v = pick(s, prev);
        prev = s;
        if (!v) continue;
        xs.push(s.time_s);
        v.forEach((y, i) => ys[i]?.push(y));
      }
      const cut = xs.findIndex((x) => x >= xs[xs.length - 1] - seconds);
      if (cut > 0) {
        xs.splice(0, cut);
        for (const y of ys) y.splice(0, cut);
      }
      dirty = true;
    };
    traceListeners.add(onSamples);
    const timer = setInterval(() => {
      if (dirty) {
        dirty = false;
        plot.setData([xs, ...ys]);
      }
    }, 200);
    const ro = new ResizeObserver(() => plot.setSize({ width: el.clientWidth, height: 190 }));
    ro.observe(el);
    return () => {
      traceListeners.delete(onSamples);
      clearInterval(timer);
      ro.disconnect();
      plot.destroy();
    };
  }, [series.join()]);
  return <div class="live-plot" ref={box} data-testid={testid} role="img" aria-label={`${title} (${unit})`} />;
}
