import { blockEnd } from '../../api/preview';
import { position } from '../../format';
import { cursor, info, loadedChain, status, toolInChainFrame } from '../../state/store';

const INDEX: Record<string, number> = { X: 0, Y: 1, Z: 2 };

/** Work and machine positions, distance to go and homed state per axis. */
export function Dro() {
  const s = status.value;
  const axes = info.value?.axes ?? [];
  const units = s?.modal?.units ?? 'mm';
  const mm = units === 'inch' ? 25.4 : 1;
  // Distance to go: the API has none, so it comes from the preview: the end of the block
  // the run is in, less where the tool is (both in the preview's frame), while a program runs.
  const chain = loadedChain.value;
  const running = s && s.mode === 'auto' && s.state !== 'idle' && s.line > 0;
  const end = chain && running ? blockEnd(chain, cursor.value, s.line) : null;
  const tool = s ? toolInChainFrame(s) : null;
  const homed = (axis: string) => s?.joints.find((j) => j.name.toUpperCase() === axis.toUpperCase())?.homed;
  return (
    <table class="dro" aria-label="Positions" data-testid="dro">
      <thead>
        <tr>
          <th scope="col">Axis</th>
          <th scope="col">Work</th>
          <th scope="col">Machine</th>
          <th scope="col" title="To the end of the executing block, from the preview (the API has no distance to go)">
            To go
          </th>
          <th scope="col">Homed</th>
        </tr>
      </thead>
      <tbody>
        {axes.map((a) => {
          const i = INDEX[a];
          const togo = end && tool && i !== undefined ? (end[i] - tool[i]) / mm : null;
          const h = homed(a);
          return (
            <tr key={a}>
              <th scope="row" class="axis">
                {a}
              </th>
              <td class="work" data-testid={`dro-work-${a}`}>
                {position(s?.work_position[a], units)}
              </td>
              <td class="machine" data-testid={`dro-machine-${a}`}>
                {position(s?.machine_position[a], units)}
              </td>
              <td class="togo">{togo === null ? '—' : position(togo, units)}</td>
              <td class={h ? 'homed yes' : 'homed no'}>{h === undefined ? '—' : h ? '● yes' : '○ no'}</td>
            </tr>
          );
        })}
      </tbody>
    </table>
  );
}
