//! FNV-1a (64 bits) over a sequence of byte fields: change detection — a basis's up-to-date
//! check, the mesh cache's keys — not security.

/// A running fingerprint (a clone goes on from the fields so far).
#[derive(Clone)]
pub struct Fingerprint(u64);

impl Default for Fingerprint {
    fn default() -> Self {
        Fingerprint(0xcbf2_9ce4_8422_2325)
    }
}

impl Fingerprint {
    /// Adds one field; fields are separated, so "ab" + "c" and "a" + "bc" differ.
    pub fn field(&mut self, bytes: &[u8]) -> &mut Self {
        for &b in bytes {
            self.eat(b);
        }
        self.eat(0xff);
        self
    }

    fn eat(&mut self, b: u8) {
        self.0 ^= u64::from(b);
        self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
    }

    /// The value so far.
    pub fn value(&self) -> u64 {
        self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_are_separated_and_the_empty_input_is_fnv_offset_basis() {
        assert_eq!(Fingerprint::default().value(), 0xcbf2_9ce4_8422_2325);
        let a = Fingerprint::default().field(b"ab").field(b"c").value();
        let b = Fingerprint::default().field(b"a").field(b"bc").value();
        assert_ne!(a, b);
        // FNV-1a of "a" is 0xaf63dc4c8601ec8c; then the separator byte.
        let mut f = Fingerprint::default();
        f.eat(b'a');
        assert_eq!(f.value(), 0xaf63_dc4c_8601_ec8c);
    }
}
