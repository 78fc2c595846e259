import { describe, expect, it } from 'vitest';
import { first, whyNot, whyNotIdle } from '../src/state/permissions';

const base = { holdsLease: false, leaseHolder: null, connected: true };

describe('who may use a control', () => {
  it('a viewer watches: every control is refused with the role named', () => {
    const viewer = { ...base, role: 'viewer' };
    expect(whyNot('viewer', viewer)).toBeNull();
    expect(whyNot('operator', viewer)).toBe('operators only: you are logged in as viewer');
    expect(whyNot('lease', viewer)).toBe('operators only: you are logged in as viewer');
    expect(whyNot('setter', viewer)).toBe('setters and admins only: you are logged in as viewer');
  });

  it('an operator needs the lease for control, not for e-stop or feed hold', () => {
    const op = { ...base, role: 'operator' };
    expect(whyNot('operator', op)).toBeNull();
    expect(whyNot('lease', op)).toBe('take the control first');
    expect(whyNot('lease', { ...op, leaseHolder: 'anna' })).toBe('anna holds the control');
    expect(whyNot('lease', { ...op, holdsLease: true })).toBeNull();
    expect(whyNot('setter', op)).toBe('setters and admins only: you are logged in as operator');
  });

  it('nothing controls a machine that is not connected', () => {
    const admin = { ...base, role: 'admin', holdsLease: true, connected: false };
    expect(whyNot('lease', admin)).toBe('the machine is not connected');
    expect(whyNot('operator', admin)).toBe('the machine is not connected');
    // Setup files are the API's: they stay editable.
    expect(whyNot('admin', admin)).toBeNull();
  });

  it('motion starts only from idle, and the first reason is given', () => {
    expect(whyNotIdle('idle')).toBeNull();
    expect(whyNotIdle('estop')).toMatch(/reset/);
    expect(whyNotIdle('held')).toMatch(/resume or stop/);
    expect(first(null, undefined, 'b', 'c')).toBe('b');
    expect(first(null)).toBeNull();
  });
});
