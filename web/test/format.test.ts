import { describe, expect, it } from 'vitest';
import { axisNumber, bytes, duration, feed, percent, position, stateLabel, stateTone } from '../src/format';

describe('positions', () => {
  it('have 3 decimals in mm and 4 in inches, a real minus sign and never "-0"', () => {
    expect(position(12.34567)).toBe('12.346');
    expect(position(-1.5)).toBe('−1.500');
    expect(position(-0.0001)).toBe('0.000');
    expect(position(-0.00001, 'inch')).toBe('0.0000');
    expect(position(1 / 3, 'inch')).toBe('0.3333');
    expect(position(undefined)).toBe('—');
    expect(position(Number.NaN)).toBe('—');
  });
});

describe('times, sizes, overrides', () => {
  it('read as a person reads them', () => {
    expect(duration(0)).toBe('0:00');
    expect(duration(39.616)).toBe('0:40');
    expect(duration(3725)).toBe('1:02:05');
    expect(duration(-1)).toBe('—');
    expect(percent(0.5)).toBe('50 %');
    expect(percent(1.25)).toBe('125 %');
    expect(bytes(583)).toBe('583 B');
    expect(bytes(17 * 1024 * 1024)).toBe('17.0 MiB');
    // 20 mm/s is F1200.
    expect(feed(20)).toBe('1200');
  });

  it('give plot ticks without "-0" and with exponents for very small or large values', () => {
    expect(axisNumber(0)).toBe('0');
    expect(axisNumber(-0)).toBe('0');
    expect(axisNumber(2.5)).toBe('2.5');
    expect(axisNumber(-0.005)).toBe('−5.0e-3');
    expect(axisNumber(100)).toBe('100');
    expect(axisNumber(12500)).toBe('1.3e+4');
  });
});

describe('states', () => {
  it('have a label and a tone', () => {
    expect(stateLabel('held')).toBe('Feed hold');
    expect(stateLabel('estop')).toBe('E-stop');
    expect(stateLabel(undefined)).toBe('Unknown');
    expect(stateTone('idle')).toBe('ok');
    expect(stateTone('running')).toBe('busy');
    expect(stateTone('held')).toBe('warn');
    expect(stateTone('fault')).toBe('alarm');
  });
});
