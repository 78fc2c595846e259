// HTTP calls of the API: the bearer token, problem documents as errors.
import type { ApiPath, Problem } from './types';

/** An error answer of the API (RFC 9457 problem document with a stable code). */
export class ApiError extends Error {
  constructor(
    readonly status: number,
    readonly code: string,
    readonly detail: string,
    readonly problem: Partial<Problem> & { extra?: unknown } = {},
  ) {
    super(`${code}: ${detail}`);
  }
}

let token: string | null = null;

export function setToken(t: string | null) {
  token = t;
}

export function getToken(): string | null {
  return token;
}

/** A path of the document with its `{parameters}` filled in. */
export function pathOf(path: ApiPath, params: Record<string, string | number> = {}): string {
  return (path as string).replace(/\{(\w+)\}/g, (_, k: string) => encodeURIComponent(String(params[k])));
}

interface Call {
  method?: string;
  params?: Record<string, string | number>;
  query?: Record<string, string | number | boolean | undefined>;
  json?: unknown;
  text?: string;
  signal?: AbortSignal;
}

async function send(path: ApiPath, call: Call): Promise<Response> {
  let url = pathOf(path, call.params);
  const q = Object.entries(call.query ?? {}).filter(([, v]) => v !== undefined);
  if (q.length) url += '?' + q.map(([k, v]) => `${encodeURIComponent(k)}=${encodeURIComponent(String(v))}`).join('&');
  const headers: Record<string, string> = {};
  if (token) headers.Authorization = `Bearer ${token}`;
  let body: BodyInit | undefined;
  if (call.json !== undefined) {
    headers['Content-Type'] = 'application/json';
    body = JSON.stringify(call.json);
  } else if (call.text !== undefined) {
    headers['Content-Type'] = 'text/plain; charset=utf-8';
    body = call.text;
  }
  let r: Response;
  try {
    r = await fetch(url, { method: call.method ?? 'GET', headers, body, signal: call.signal });
  } catch (e) {
    if ((e as Error).name === 'AbortError') throw e;
    throw new ApiError(0, 'hmi.unreachable', 'the API server does not answer');
  }
  if (!r.ok) {
    let p: Partial<Problem> & { extra?: unknown } = {};
    try {
      p = await r.json();
    } catch {
      /* not a problem document */
    }
    throw new ApiError(r.status, p.code ?? `http.${r.status}`, p.detail ?? r.statusText, p);
  }
  return r;
}

/** A call answering JSON (or nothing, for 204). */
export async function api<T>(path: ApiPath, call: Call = {}): Promise<T> {
  const r = await send(path, call);
  if (r.status === 204) return undefined as T;
  return (await r.json()) as T;
}

export async function apiText(path: ApiPath, call: Call = {}): Promise<string> {
  return (await send(path, call)).text();
}

export async function apiBytes(path: ApiPath, call: Call = {}): Promise<ArrayBuffer> {
  return (await send(path, call)).arrayBuffer();
}
