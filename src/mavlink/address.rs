//! Connection strings: `serial:/dev/ttyS0:921600`, `udpin:0.0.0.0:14550`,
//! `udpout:127.0.0.1:14550`, `tcpin:0.0.0.0:5760`, `tcpout:127.0.0.1:5760`.

use mavlink_core::ConnectionAddress;

/// Why a connection string is not usable.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum AddressError {
    /// Not one of the supported forms.
    #[error("`{0}`: expected serial:DEVICE:BAUD, udpin:HOST:PORT, udpout:HOST:PORT, tcpin:HOST:PORT or tcpout:HOST:PORT")]
    Form(String),
    /// The baud rate is not a positive number.
    #[error("`{0}`: the baud rate must be a positive integer")]
    Baud(String),
    /// The port is not a number in 1..=65535.
    #[error("`{0}`: the port must be a number in 1..=65535")]
    Port(String),
}

/// Checks a connection string and returns the `mavlink` crate's address for it.
pub fn parse_connection(s: &str) -> Result<ConnectionAddress, AddressError> {
    let form = || AddressError::Form(s.to_owned());
    let (scheme, rest) = s.split_once(':').ok_or_else(form)?;
    match scheme {
        "serial" => {
            let (device, baud) = rest.rsplit_once(':').ok_or_else(form)?;
            if device.is_empty() {
                return Err(form());
            }
            match baud.parse::<u32>() {
                Ok(b) if b > 0 => {}
                _ => return Err(AddressError::Baud(s.to_owned())),
            }
        }
        "udpin" | "udpout" | "tcpin" | "tcpout" => {
            let (host, port) = rest.rsplit_once(':').ok_or_else(form)?;
            if host.is_empty() {
                return Err(form());
            }
            match port.parse::<u16>() {
                Ok(p) if p > 0 => {}
                _ => return Err(AddressError::Port(s.to_owned())),
            }
        }
        _ => return Err(form()),
    }
    ConnectionAddress::parse_address(s).map_err(|_| form())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accepts_the_documented_forms() {
        for s in [
            "serial:/dev/ttyS0:921600",
            "udpin:0.0.0.0:14550",
            "udpout:127.0.0.1:14550",
            "tcpin:0.0.0.0:5760",
            "tcpout:localhost:5760",
        ] {
            assert!(parse_connection(s).is_ok(), "{s}");
        }
    }

    #[test]
    fn names_the_problem() {
        assert!(matches!(
            parse_connection("udp:1.2.3.4:5"),
            Err(AddressError::Form(_))
        ));
        assert!(matches!(
            parse_connection("udpin:1.2.3.4"),
            Err(AddressError::Form(_))
        ));
        assert!(matches!(
            parse_connection("udpin:1.2.3.4:0"),
            Err(AddressError::Port(_))
        ));
        assert!(matches!(
            parse_connection("serial:/dev/ttyS0:fast"),
            Err(AddressError::Baud(_))
        ));
        assert!(matches!(
            parse_connection("serial::57600"),
            Err(AddressError::Form(_))
        ));
        assert!(matches!(parse_connection(""), Err(AddressError::Form(_))));
    }
}
