//! A plain classical-CAN frame implementing [`embedded_can::Frame`], so the codec needs no
//! driver: firmware copies it into its CAN peripheral, the host into a socket or a log.

use embedded_can::{ExtendedId, Id, StandardId};

/// A classical CAN frame (up to 8 data bytes), data or remote.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct CanFrame {
    id: Id,
    remote: bool,
    dlc: u8,
    data: [u8; 8],
}

impl CanFrame {
    /// A data frame with an extended (29-bit) identifier; `None` if the id does not fit in
    /// 29 bits or `data` is longer than 8 bytes.
    pub fn new_extended(id: u32, data: &[u8]) -> Option<Self> {
        embedded_can::Frame::new(ExtendedId::new(id)?, data)
    }

    /// A data frame with a standard (11-bit) identifier; `None` if the id does not fit in
    /// 11 bits or `data` is longer than 8 bytes.
    pub fn new_standard(id: u16, data: &[u8]) -> Option<Self> {
        embedded_can::Frame::new(StandardId::new(id)?, data)
    }

    /// A full 8-byte data frame with an extended identifier (infallible).
    pub const fn from_extended(id: ExtendedId, data: [u8; 8]) -> Self {
        Self { id: Id::Extended(id), remote: false, dlc: 8, data }
    }

    /// The raw identifier (11 or 29 bits) without the format flag.
    pub fn raw_id(&self) -> u32 {
        raw_id(self.id)
    }

    /// Copies any [`embedded_can::Frame`] (for example a socketcan frame) into this type.
    /// `None` for a frame whose length exceeds classical CAN.
    pub fn from_frame<F: embedded_can::Frame>(f: &F) -> Option<Self> {
        if f.is_remote_frame() {
            <Self as embedded_can::Frame>::new_remote(f.id(), f.dlc())
        } else {
            <Self as embedded_can::Frame>::new(f.id(), f.data())
        }
    }
}

/// The raw value of an identifier (11 or 29 bits) without the format flag.
pub fn raw_id(id: Id) -> u32 {
    match id {
        Id::Standard(s) => u32::from(s.as_raw()),
        Id::Extended(e) => e.as_raw(),
    }
}

impl embedded_can::Frame for CanFrame {
    fn new(id: impl Into<Id>, data: &[u8]) -> Option<Self> {
        let len = data.len();
        if len > 8 {
            return None;
        }
        let mut buf = [0u8; 8];
        buf.get_mut(..len)?.copy_from_slice(data);
        Some(Self { id: id.into(), remote: false, dlc: len as u8, data: buf })
    }

    fn new_remote(id: impl Into<Id>, dlc: usize) -> Option<Self> {
        if dlc > 8 {
            return None;
        }
        Some(Self { id: id.into(), remote: true, dlc: dlc as u8, data: [0; 8] })
    }

    fn is_extended(&self) -> bool {
        matches!(self.id, Id::Extended(_))
    }

    fn is_remote_frame(&self) -> bool {
        self.remote
    }

    fn id(&self) -> Id {
        self.id
    }

    fn dlc(&self) -> usize {
        usize::from(self.dlc)
    }

    fn data(&self) -> &[u8] {
        if self.remote {
            &[]
        } else {
            // `dlc <= 8` is an invariant of every constructor.
            self.data.get(..usize::from(self.dlc)).unwrap_or(&[])
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use embedded_can::Frame;

    #[test]
    fn constructors_check_limits() {
        assert!(CanFrame::new_extended(0x1FFF_FFFF, &[1; 8]).is_some());
        assert!(CanFrame::new_extended(0x2000_0000, &[]).is_none());
        assert!(CanFrame::new_standard(0x800, &[]).is_none());
        assert!(CanFrame::new_standard(0x7FF, &[0; 9]).is_none());
        let f = CanFrame::new_standard(0x123, &[1, 2, 3]).unwrap();
        assert_eq!((f.raw_id(), f.dlc(), f.data(), f.is_standard()), (0x123, 3, &[1u8, 2, 3][..], true));
        let r = CanFrame::new_remote(StandardId::new(0x10).unwrap(), 4).unwrap();
        assert!(r.is_remote_frame());
        assert_eq!((r.dlc(), r.data().len()), (4, 0));
        assert_eq!(CanFrame::from_frame(&r), Some(r));
    }
}
