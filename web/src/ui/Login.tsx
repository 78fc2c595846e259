import { useState } from 'preact/hooks';
import { changePassword, errorText, login, session } from '../state/store';

export function Login() {
  const [user, setUser] = useState('');
  const [password, setPassword] = useState('');
  const [next, setNext] = useState('');
  const [error, setError] = useState<string | null>(null);
  const [busy, setBusy] = useState(false);
  const mustChange = session.value?.passwordChangeRequired;
  const submit = async (e: Event) => {
    e.preventDefault();
    setBusy(true);
    setError(null);
    try {
      if (mustChange) await changePassword(password, next);
      else await login(user, password);
    } catch (err) {
      setError(errorText(err));
    } finally {
      setBusy(false);
    }
  };
  return (
    <main class="login">
      <form class="login-box" onSubmit={submit} aria-label="Log in">
        <h1>rtcnc</h1>
        {mustChange ? (
          <>
            <p>This is a one-time password: choose your own (at least 8 characters).</p>
            <label>
              One-time password
              <input type="password" value={password} onInput={(e) => setPassword(e.currentTarget.value)} autocomplete="current-password" />
            </label>
            <label>
              New password
              <input type="password" value={next} onInput={(e) => setNext(e.currentTarget.value)} autocomplete="new-password" />
            </label>
          </>
        ) : (
          <>
            <label>
              User
              <input name="user" value={user} onInput={(e) => setUser(e.currentTarget.value)} autocomplete="username" autofocus />
            </label>
            <label>
              Password
              <input name="password" type="password" value={password} onInput={(e) => setPassword(e.currentTarget.value)} autocomplete="current-password" />
            </label>
          </>
        )}
        {error && (
          <p class="error" role="alert">
            {error}
          </p>
        )}
        <button type="submit" class="btn primary" disabled={busy} data-testid="login-submit">
          {mustChange ? 'Change password' : 'Log in'}
        </button>
      </form>
    </main>
  );
}
