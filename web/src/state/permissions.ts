// Who may use which control, and why not: a control a role or the moment does not allow is
// shown disabled with this reason (the server checks the same again).
import type { Role } from '../api/types';

export const ROLES: Role[] = ['viewer', 'operator', 'setter', 'admin'];

export function rank(role: string | undefined): number {
  return ROLES.indexOf((role ?? 'viewer') as Role);
}

export interface Who {
  role: string;
  /** This session holds the control lease. */
  holdsLease: boolean;
  /** Who holds it (user name), if anyone. */
  leaseHolder: string | null | undefined;
  /** The API answers and the machine process is attached. */
  connected: boolean;
}

/**
 * What a control needs: `viewer` (anyone logged in), `operator` (an operator, lease or not:
 * e-stop, feed hold, uploads, acknowledging alarms), `lease` (an operator holding the
 * control lease), `setter`, `admin`.
 */
export type Need = 'viewer' | 'operator' | 'lease' | 'setter' | 'admin';

/** Why a control is not allowed now, or null when it is. */
export function whyNot(need: Need, who: Who): string | null {
  const role = rank(who.role);
  const named = `you are logged in as ${who.role}`;
  switch (need) {
    case 'viewer':
      return null;
    case 'operator':
      if (role < rank('operator')) return `operators only: ${named}`;
      return who.connected ? null : 'the machine is not connected';
    case 'lease':
      if (role < rank('operator')) return `operators only: ${named}`;
      if (!who.connected) return 'the machine is not connected';
      if (!who.holdsLease) {
        return who.leaseHolder ? `${who.leaseHolder} holds the control` : 'take the control first';
      }
      return null;
    case 'setter':
      return role < rank('setter') ? `setters and admins only: ${named}` : null;
    case 'admin':
      return role < rank('admin') ? `admins only: ${named}` : null;
  }
}

/** Why a state forbids starting motion (cycle start, MDI, jog, homing), or null. */
export function whyNotIdle(state: string | undefined): string | null {
  switch (state) {
    case 'idle':
      return null;
    case 'estop':
      return 'the machine is in e-stop: reset it first';
    case 'fault':
      return 'the machine has a fault: reset it first';
    case 'starting':
      return 'the machine is starting';
    case 'running':
    case 'waiting_for_logic':
      return 'the machine is busy';
    case 'held':
      return 'the machine is held: resume or stop first';
    case 'paused':
      return 'the program is paused: resume or stop first';
    default:
      return 'the machine state is not known';
  }
}

/** The first reason of several, or null. */
export function first(...reasons: (string | null | undefined)[]): string | null {
  for (const r of reasons) if (r) return r;
  return null;
}
