import { position } from '../../format';
import { info, status } from '../../state/store';

/** Work and machine positions, distance to go and homed state per axis. */
export function Dro() {
  const s = status.value;
  const axes = info.value?.axes ?? [];
  const units = s?.modal?.units ?? 'mm';
  // The status gives the distance to go in machine units (mm), shown in program units.
  const mm = units === 'inch' ? 25.4 : 1;
  const homed = (axis: string) => s?.joints.find((j) => j.name.toUpperCase() === axis.toUpperCase())?.homed;
  return (
    <table class="dro" aria-label="Positions" data-testid="dro">
      <thead>
        <tr>
          <th scope="col">Axis</th>
          <th scope="col">Work</th>
          <th scope="col">Machine</th>
          <th scope="col" title="To the end of the executing program or MDI line">
            To go
          </th>
          <th scope="col">Homed</th>
        </tr>
      </thead>
      <tbody>
        {axes.map((a) => {
          const d = s?.distance_to_go?.[a];
          const togo = d === undefined ? null : d / mm;
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
              <td class="togo" data-testid={`dro-togo-${a}`}>{togo === null ? '—' : position(togo, units)}</td>
              <td class={h ? 'homed yes' : 'homed no'} data-testid={`dro-homed-${a}`}>{h === undefined ? '—' : h ? '● yes' : '○ no'}</td>
            </tr>
          );
        })}
      </tbody>
    </table>
  );
}
