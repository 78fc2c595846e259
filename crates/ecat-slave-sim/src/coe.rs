//! The CoE (CANopen over EtherCAT) mailbox server: SDO upload and download, expedited,
//! normal and segmented (ETG.1000.6 §5.6.2), with abort codes.
//!
//! A mailbox message is a 6-byte mailbox header (length, address, channel/priority,
//! type/counter), a 2-byte CoE header (number, service) and the SDO: a command byte, index,
//! sub-index and data.

use crate::application::Application;
use crate::dictionary::abort;
use crate::esc::AlState;
use crate::frame::{read_u16, read_u32, write_u16, write_u32};

/// Mailbox header length.
pub const MAILBOX_HEADER_LEN: usize = 6;
/// Mailbox type of CoE.
pub const MAILBOX_TYPE_COE: u8 = 3;
/// Mailbox type of a mailbox error reply.
const MAILBOX_TYPE_ERROR: u8 = 0;
/// Mailbox error: the service (protocol) is not supported.
const MAILBOX_ERROR_UNSUPPORTED_PROTOCOL: u16 = 0x0002;
/// CoE services.
const SERVICE_SDO_REQUEST: u16 = 2;
const SERVICE_SDO_RESPONSE: u16 = 3;

/// CoE header + SDO command + index + sub-index.
const SDO_HEADER_LEN: usize = 2 + 4;

/// A transfer spanning several mailbox messages.
#[derive(Debug, Clone, PartialEq)]
enum Transfer {
    Idle,
    /// Segmented upload: the value and how much has gone.
    Upload {
        data: Vec<u8>,
        sent: usize,
        toggle: bool,
    },
    /// Segmented download: where to, the announced size, what has come.
    Download {
        index: u16,
        sub_index: u8,
        size: usize,
        data: Vec<u8>,
        toggle: bool,
    },
}

/// One device's CoE server state.
#[derive(Debug, Clone, PartialEq)]
pub struct CoeServer {
    transfer: Transfer,
    counter: u8,
}

impl Default for CoeServer {
    fn default() -> Self {
        Self::new()
    }
}

impl CoeServer {
    /// A server with no transfer under way.
    pub fn new() -> Self {
        Self {
            transfer: Transfer::Idle,
            counter: 0,
        }
    }

    /// Answers the mailbox message in `request` (as written into SM0) by filling
    /// `response` (the SM1 buffer); returns whether there is a response.
    pub fn handle(
        &mut self,
        request: &[u8],
        response: &mut [u8],
        application: &mut dyn Application,
        state: AlState,
    ) -> bool {
        response.fill(0);
        let Some(length) = read_u16(request, 0) else {
            return false;
        };
        let kind = request.get(5).copied().unwrap_or(0) & 0x0F;
        let end = (MAILBOX_HEADER_LEN + usize::from(length)).min(request.len());
        let Some(body) = request.get(MAILBOX_HEADER_LEN..end) else {
            return false;
        };
        self.counter = if self.counter >= 7 {
            1
        } else {
            self.counter + 1
        };
        if kind != MAILBOX_TYPE_COE {
            let mut error = [0u8; 4];
            write_u16(&mut error, 0, 0x0001);
            write_u16(&mut error, 2, MAILBOX_ERROR_UNSUPPORTED_PROTOCOL);
            return self.reply(response, MAILBOX_TYPE_ERROR, &error);
        }
        let service = read_u16(body, 0).unwrap_or(0) >> 12;
        if service != SERVICE_SDO_REQUEST || body.len() < SDO_HEADER_LEN {
            return self.sdo_abort(response, 0, 0, abort::COMMAND);
        }
        let command = body[2];
        let index = read_u16(body, 3).unwrap_or(0);
        let sub_index = body[5];
        let ccs = command >> 5;
        match ccs {
            // Initiate download.
            1 => self.initiate_download(response, application, state, body),
            // Download segment.
            0 => self.download_segment(response, application, state, body),
            // Initiate upload.
            2 => self.initiate_upload(response, application, index, sub_index),
            // Upload segment.
            3 => self.upload_segment(response, command),
            // Abort from the master ends any transfer.
            4 => {
                self.transfer = Transfer::Idle;
                false
            }
            _ => self.sdo_abort(response, index, sub_index, abort::COMMAND),
        }
    }

    fn initiate_download(
        &mut self,
        response: &mut [u8],
        application: &mut dyn Application,
        state: AlState,
        body: &[u8],
    ) -> bool {
        self.transfer = Transfer::Idle;
        let command = body[2];
        let index = read_u16(body, 3).unwrap_or(0);
        let sub_index = body[5];
        if command & 0x10 != 0 {
            // Complete access is not offered (the SII's CoE details say so).
            return self.sdo_abort(response, index, sub_index, abort::UNSUPPORTED_ACCESS);
        }
        let expedited = command & 0x02 != 0;
        let size_indicated = command & 0x01 != 0;
        if expedited {
            let unused = if size_indicated {
                usize::from((command >> 2) & 0x03)
            } else {
                0
            };
            let Some(data) = body.get(6..10 - unused) else {
                return self.sdo_abort(response, index, sub_index, abort::LENGTH);
            };
            return match application.download(index, sub_index, data, state) {
                Ok(()) => self.download_response(response, index, sub_index),
                Err(code) => self.sdo_abort(response, index, sub_index, code),
            };
        }
        let Some(size) = read_u32(body, 6) else {
            return self.sdo_abort(response, index, sub_index, abort::LENGTH);
        };
        let size = size as usize;
        let data = body.get(10..).unwrap_or(&[]);
        if data.len() >= size {
            // Normal transfer: everything came in the first message.
            let data = &data[..size];
            return match application.download(index, sub_index, data, state) {
                Ok(()) => self.download_response(response, index, sub_index),
                Err(code) => self.sdo_abort(response, index, sub_index, code),
            };
        }
        // Check what can be checked before the segments come: the object, its access.
        if let Some(dictionary) = application.dictionary() {
            if let Err(code) = dictionary.check_download(index, sub_index, &[], state) {
                if code != abort::LENGTH {
                    return self.sdo_abort(response, index, sub_index, code);
                }
            }
            let too_long = dictionary
                .entry(index, sub_index)
                .is_some_and(|e| size > e.max_len);
            if too_long {
                return self.sdo_abort(response, index, sub_index, abort::LENGTH);
            }
        }
        self.transfer = Transfer::Download {
            index,
            sub_index,
            size,
            data: data.to_vec(),
            toggle: false,
        };
        self.download_response(response, index, sub_index)
    }

    fn download_segment(
        &mut self,
        response: &mut [u8],
        application: &mut dyn Application,
        state: AlState,
        body: &[u8],
    ) -> bool {
        let command = body[2];
        let Transfer::Download {
            index,
            sub_index,
            size,
            data,
            toggle,
        } = &mut self.transfer
        else {
            return self.sdo_abort(response, 0, 0, abort::COMMAND);
        };
        let (index, sub_index) = (*index, *sub_index);
        let segment_toggle = command & 0x10 != 0;
        if segment_toggle != *toggle {
            self.transfer = Transfer::Idle;
            return self.sdo_abort(response, index, sub_index, abort::TOGGLE);
        }
        // The segment's data starts after the command byte; a short segment is padded to 7
        // bytes with the unused count in bits 1-3.
        let mut segment = body.get(3..).unwrap_or(&[]);
        if segment.len() == 7 {
            let unused = usize::from((command >> 1) & 0x07);
            segment = &segment[..7 - unused];
        }
        data.extend_from_slice(segment);
        let last = command & 0x01 != 0;
        let reply_toggle = *toggle;
        *toggle = !*toggle;
        if data.len() > *size || (last && data.len() != *size) {
            self.transfer = Transfer::Idle;
            return self.sdo_abort(response, index, sub_index, abort::LENGTH);
        }
        if last {
            let Transfer::Download { data, .. } =
                std::mem::replace(&mut self.transfer, Transfer::Idle)
            else {
                return false;
            };
            if let Err(code) = application.download(index, sub_index, &data, state) {
                return self.sdo_abort(response, index, sub_index, code);
            }
        }
        let sdo = [0x20 | (u8::from(reply_toggle) << 4), 0, 0, 0, 0, 0, 0, 0];
        self.sdo_reply(response, &sdo)
    }

    fn initiate_upload(
        &mut self,
        response: &mut [u8],
        application: &mut dyn Application,
        index: u16,
        sub_index: u8,
    ) -> bool {
        self.transfer = Transfer::Idle;
        let Some(dictionary) = application.dictionary() else {
            return self.sdo_abort(response, index, sub_index, abort::NO_OBJECT);
        };
        let value = match dictionary.upload(index, sub_index) {
            Ok(value) => value.to_vec(),
            Err(code) => return self.sdo_abort(response, index, sub_index, code),
        };
        let mut sdo = [0u8; 8];
        write_u16(&mut sdo, 1, index);
        sdo[3] = sub_index;
        if (1..=4).contains(&value.len()) {
            let unused = (4 - value.len()) as u8;
            sdo[0] = 0x40 | (unused << 2) | 0x02 | 0x01;
            sdo[4..4 + value.len()].copy_from_slice(&value);
            return self.sdo_reply(response, &sdo);
        }
        // Normal upload: the size, then as much data as the mailbox holds.
        sdo[0] = 0x40 | 0x01;
        write_u32(&mut sdo, 4, value.len() as u32);
        let room = response
            .len()
            .saturating_sub(MAILBOX_HEADER_LEN + SDO_HEADER_LEN + 4);
        let first = value.len().min(room);
        let mut message = Vec::with_capacity(8 + first);
        message.extend_from_slice(&sdo);
        message.extend_from_slice(&value[..first]);
        if first < value.len() {
            self.transfer = Transfer::Upload {
                data: value,
                sent: first,
                toggle: false,
            };
        }
        self.sdo_reply(response, &message)
    }

    fn upload_segment(&mut self, response: &mut [u8], command: u8) -> bool {
        let room = response.len().saturating_sub(MAILBOX_HEADER_LEN + 3);
        let Transfer::Upload { data, sent, toggle } = &mut self.transfer else {
            return self.sdo_abort(response, 0, 0, abort::COMMAND);
        };
        let segment_toggle = command & 0x10 != 0;
        if segment_toggle != *toggle {
            self.transfer = Transfer::Idle;
            return self.sdo_abort(response, 0, 0, abort::TOGGLE);
        }
        let chunk = (data.len() - *sent).min(room);
        let last = *sent + chunk == data.len();
        let mut message = Vec::with_capacity(1 + chunk.max(7));
        let unused = 7usize.saturating_sub(chunk) as u8;
        message.push((u8::from(*toggle) << 4) | (unused << 1) | u8::from(last));
        message.extend_from_slice(&data[*sent..*sent + chunk]);
        message.resize(1 + chunk.max(7), 0);
        *sent += chunk;
        *toggle = !*toggle;
        if last {
            self.transfer = Transfer::Idle;
        }
        self.sdo_reply(response, &message)
    }

    fn download_response(&mut self, response: &mut [u8], index: u16, sub_index: u8) -> bool {
        let mut sdo = [0u8; 8];
        sdo[0] = 0x60;
        write_u16(&mut sdo, 1, index);
        sdo[3] = sub_index;
        self.sdo_reply(response, &sdo)
    }

    fn sdo_abort(&mut self, response: &mut [u8], index: u16, sub_index: u8, code: u32) -> bool {
        self.transfer = Transfer::Idle;
        let mut sdo = [0u8; 8];
        sdo[0] = 0x80;
        write_u16(&mut sdo, 1, index);
        sdo[3] = sub_index;
        write_u32(&mut sdo, 4, code);
        // An abort travels as an SDO request (ETG.1000.6 §5.6.2.7), not a response.
        self.sdo_message(response, SERVICE_SDO_REQUEST, &sdo)
    }

    fn sdo_reply(&mut self, response: &mut [u8], sdo: &[u8]) -> bool {
        self.sdo_message(response, SERVICE_SDO_RESPONSE, sdo)
    }

    fn sdo_message(&mut self, response: &mut [u8], service: u16, sdo: &[u8]) -> bool {
        let mut body = Vec::with_capacity(2 + sdo.len());
        body.extend_from_slice(&(service << 12).to_le_bytes());
        body.extend_from_slice(sdo);
        self.reply(response, MAILBOX_TYPE_COE, &body)
    }

    fn reply(&mut self, response: &mut [u8], kind: u8, body: &[u8]) -> bool {
        let Some(out) = response.get_mut(..MAILBOX_HEADER_LEN + body.len()) else {
            return false;
        };
        write_u16(out, 0, body.len() as u16);
        out[2..5].copy_from_slice(&[0, 0, 0]);
        out[5] = kind | (self.counter << 4);
        out[MAILBOX_HEADER_LEN..].copy_from_slice(body);
        true
    }
}
