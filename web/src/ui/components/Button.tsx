import type { ComponentChildren } from 'preact';

interface Props {
  /** Why the control is not allowed now (shown, and the control disabled), or null. */
  why?: string | null;
  onClick?: () => void;
  tone?: 'primary' | 'go' | 'stop' | 'warn' | 'plain';
  pressed?: boolean;
  children: ComponentChildren;
  label?: string;
  testid?: string;
  class?: string;
  title?: string;
}

/** A button that says why it is disabled. */
export function Button({ why, onClick, tone = 'plain', pressed, children, label, testid, class: cls, title }: Props) {
  const disabled = !!why;
  return (
    <button
      type="button"
      class={`btn ${tone} ${cls ?? ''}`}
      disabled={disabled}
      aria-disabled={disabled}
      aria-pressed={pressed === undefined ? undefined : pressed}
      aria-label={label}
      title={why ?? title ?? undefined}
      data-testid={testid}
      data-why={why ?? undefined}
      onClick={disabled ? undefined : onClick}
    >
      {children}
    </button>
  );
}

/** The reason under a group of disabled controls. */
export function Why({ why }: { why: string | null }) {
  return why ? <p class="why">{why}</p> : null;
}
