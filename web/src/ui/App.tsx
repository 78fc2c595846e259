import { signal } from '@preact/signals';
import { useEffect } from 'preact/hooks';
import { stateLabel, stateTone } from '../format';
import {
  connected,
  holdsLease,
  info,
  linkDownReason,
  linkUp,
  logout,
  notices,
  reason,
  releaseLease,
  resume,
  run,
  session,
  status,
  takeLease,
  unacknowledged,
  command,
} from '../state/store';
import { Button } from './components/Button';
import { Login } from './Login';
import { Diagnostics } from './screens/Diagnostics';
import { Manual } from './screens/Manual';
import { Operate } from './screens/Operate';
import { Programs } from './screens/Programs';
import { Setup } from './screens/Setup';

const SCREENS = [
  ['operate', 'Operate', Operate],
  ['manual', 'Manual', Manual],
  ['programs', 'Programs', Programs],
  ['setup', 'Setup', Setup],
  ['diagnostics', 'Diagnostics', Diagnostics],
] as const;
type ScreenName = (typeof SCREENS)[number][0];

function fromPath(): ScreenName {
  const p = location.pathname.replace(/^\//, '');
  return (SCREENS.find(([n]) => n === p)?.[0] ?? 'operate') as ScreenName;
}

export const screen = signal<ScreenName>(fromPath());

export function go(to: ScreenName) {
  if (screen.value === to) return;
  history.pushState(null, '', `/${to}`);
  screen.value = to;
}

const resumed = signal<'pending' | 'done'>('pending');

export function App() {
  useEffect(() => {
    const onPop = () => (screen.value = fromPath());
    addEventListener('popstate', onPop);
    void resume().finally(() => (resumed.value = 'done'));
    return () => removeEventListener('popstate', onPop);
  }, []);
  if (resumed.value === 'pending') return <main class="login" aria-busy="true" />;
  const s = session.value;
  if (!s || s.passwordChangeRequired || !info.value) return <Login />;
  const Screen = SCREENS.find(([n]) => n === screen.value)![2];
  return (
    <div class="app">
      <TopBar />
      <LinkBanner />
      <nav class="tabs" aria-label="Screens">
        {SCREENS.map(([name, label]) => (
          <a
            href={`/${name}`}
            class={screen.value === name ? 'tab active' : 'tab'}
            aria-current={screen.value === name ? 'page' : undefined}
            onClick={(e) => {
              e.preventDefault();
              go(name);
            }}
          >
            {label}
            {name === 'diagnostics' && unacknowledged.value > 0 && (
              <span class="badge" aria-label={`${unacknowledged.value} unacknowledged alarms`}>
                {unacknowledged.value}
              </span>
            )}
          </a>
        ))}
      </nav>
      <main class={`screen screen-${screen.value}`} aria-label={SCREENS.find(([n]) => n === screen.value)![1]}>
        <Screen />
      </main>
      <Notices />
    </div>
  );
}

function TopBar() {
  const s = status.value;
  const me = session.value!;
  const holder = s?.lease_holder;
  const canTakeOver = me.role === 'admin' && holder && !holdsLease.value;
  return (
    <header class="topbar">
      <div class="machine">
        <span class="machine-name">{info.value?.machine ?? s?.machine}</span>
        <span class={`state tone-${stateTone(s?.state)}`} data-testid="state" role="status" aria-live="polite">
          {connected.value ? stateLabel(s?.state) : 'Not connected'}
        </span>
        {s?.hold_message ? (
          <span class="hold-cause" data-testid="hold-cause">
            {s.hold_message}
          </span>
        ) : null}
        <span class="mode" data-testid="mode">
          {s?.mode?.toUpperCase()}
        </span>
      </div>
      <div class="lease" data-testid="lease">
        <span class="lease-holder">
          Control: <strong>{holdsLease.value ? 'you' : holder ?? 'free'}</strong>
        </span>
        {holdsLease.value ? (
          <Button testid="lease-release" onClick={() => run('Release control', releaseLease)}>
            Release
          </Button>
        ) : canTakeOver ? (
          <Button testid="lease-take-over" tone="warn" why={reason('operator')} onClick={() => run('Take over', () => takeLease(true))}>
            Take over from {holder}
          </Button>
        ) : (
          <Button
            testid="lease-take"
            tone="primary"
            why={reason('operator') ?? (holder ? `${holder} holds the control` : null)}
            onClick={() => run('Take control', () => takeLease(false))}
          >
            Take control
          </Button>
        )}
      </div>
      <div class="user">
        <span>
          {me.user} <em>({me.role})</em>
        </span>
        <Button testid="logout" onClick={() => void logout()}>
          Log out
        </Button>
      </div>
      <div class="safety">
        <Button testid="reset" tone="go" why={reason('lease')} onClick={() => run('Reset', () => command('/api/control/reset'))}>
          Reset
        </Button>
        <button
          type="button"
          class="estop"
          data-testid="estop"
          disabled={!!reason('operator')}
          title={reason('operator') ?? 'Emergency stop (any operator, with or without the control)'}
          onClick={() => run('E-stop', () => command('/api/control/estop'))}
        >
          E-STOP
        </button>
      </div>
    </header>
  );
}

function LinkBanner() {
  const s = status.value;
  let text: string | null = null;
  if (!linkUp.value) text = `Connection to the machine lost: ${linkDownReason.value ?? 'connecting'}. Reconnecting…`;
  else if (s && !s.connected) text = 'The machine process does not answer: the values shown are the last known. Waiting for it…';
  if (!text) return null;
  return (
    <div class="banner" role="alert" data-testid="link-banner">
      {text}
    </div>
  );
}

function Notices() {
  return (
    <div class="notices" aria-live="assertive">
      {notices.value.map((n) => (
        <div key={n.id} class={`notice ${n.tone}`} role={n.tone === 'error' ? 'alert' : 'status'}>
          {n.text}
        </div>
      ))}
    </div>
  );
}
