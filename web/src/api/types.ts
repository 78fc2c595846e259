// The API's documents, from the types openapi-typescript generates out of the committed
// OpenAPI document (docs/openapi.json): nothing here is typed by hand.
import type { components, paths } from './schema';

type S = components['schemas'];
export type Status = S['Status'];
export type Ack = S['Ack'];
export type ApiInfo = S['ApiInfo'];
export type SessionInfo = S['SessionInfo'];
export type Lease = S['Lease'];
export type Event = S['Event'];
export type EventPage = S['EventPage'];
export type ProgramInfo = S['ProgramInfo'];
export type ProgramError = S['ProgramError'];
export type ProgramCheck = S['ProgramCheck'];
export type Estimate = S['Estimate'];
export type Tool = S['Tool'];
export type WorkOffset = S['WorkOffset'];
export type FaultRecord = S['FaultRecord'];
export type Timing = S['Timing'];
export type TaskTiming = S['TaskTiming'];
export type PlcVariableInfo = S['PlcVariableInfo'];
export type MachineFile = S['MachineFile'];
export type MachineFileSaved = S['MachineFileSaved'];
export type Problem = S['Problem'];
export type Jog = S['Jog'];
export type OverridesRequest = S['OverridesRequest'];
export type Role = 'viewer' | 'operator' | 'setter' | 'admin';

/** The API's paths, checked against the document. */
export type ApiPath = keyof paths;
