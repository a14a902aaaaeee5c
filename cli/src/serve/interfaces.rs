//! The addresses of this machine's network interfaces (`getifaddrs`): in
//! network mode, a request may name the preview by any of them (a client
//! that typed the machine's address), and the URL printed for other
//! machines uses one they can reach.

use std::net::{IpAddr, Ipv4Addr, Ipv6Addr};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Every address of every interface, loopback included, without repeats.
#[cfg(unix)]
pub fn addresses() -> Vec<IpAddr> {
    let mut list: *mut libc::ifaddrs = std::ptr::null_mut();
    // SAFETY: on success `getifaddrs` points `list` at a linked list it
    // allocated, valid until `freeifaddrs`, which is called once below.
    if unsafe { libc::getifaddrs(&mut list) } != 0 {
        return Vec::new();
    }
    let mut out: Vec<IpAddr> = Vec::new();
    let mut at = list;
    while !at.is_null() {
        // SAFETY: `at` is a node of the list, alive until `freeifaddrs`.
        let entry = unsafe { &*at };
        let sa = entry.ifa_addr;
        if !sa.is_null() {
            // SAFETY: `sa` points at a socket address whose family says
            // its real type; only the two read here are cast to.
            let ip = match i32::from(unsafe { (*sa).sa_family }) {
                libc::AF_INET => {
                    let a = unsafe { &*sa.cast::<libc::sockaddr_in>() };
                    Some(IpAddr::V4(Ipv4Addr::from(u32::from_be(a.sin_addr.s_addr))))
                }
                libc::AF_INET6 => {
                    let a = unsafe { &*sa.cast::<libc::sockaddr_in6>() };
                    Some(IpAddr::V6(Ipv6Addr::from(a.sin6_addr.s6_addr)))
                }
                _ => None,
            };
            if let Some(ip) = ip.filter(|ip| !out.contains(ip)) {
                out.push(ip);
            }
        }
        at = entry.ifa_next;
    }
    // SAFETY: the list `getifaddrs` made, freed once; no reference to it
    // outlives this line.
    unsafe { libc::freeifaddrs(list) };
    out
}

#[cfg(not(unix))]
pub fn addresses() -> Vec<IpAddr> {
    Vec::new()
}

/// Whether other machines may reach `ip`: not loopback, not unspecified,
/// not link-local (a URL with one needs the interface's zone).
pub fn reachable(ip: IpAddr) -> bool {
    let ip = ip.to_canonical();
    !ip.is_loopback()
        && !ip.is_unspecified()
        && !ip.is_multicast()
        && match ip {
            IpAddr::V4(v4) => !v4.is_link_local(),
            IpAddr::V6(v6) => (v6.segments()[0] & 0xffc0) != 0xfe80,
        }
}

/// The addresses a server bound to `bind` (unspecified: every interface
/// of its family; `::` takes IPv4 too) is reachable at from other
/// machines, IPv4 first.
pub fn urls_for(bind: IpAddr, all: &[IpAddr]) -> Vec<IpAddr> {
    let bind = bind.to_canonical();
    if !bind.is_unspecified() {
        return if reachable(bind) {
            vec![bind]
        } else {
            Vec::new()
        };
    }
    let mut out: Vec<IpAddr> = all
        .iter()
        .map(|ip| ip.to_canonical())
        .filter(|ip| reachable(*ip) && (bind.is_ipv6() || ip.is_ipv4()))
        .collect();
    out.sort_by_key(|ip| ip.is_ipv6());
    out.dedup();
    out
}

/// The interfaces' addresses, listed again when asked about an address
/// not among them (an interface that came up since, a new DHCP lease), at
/// most once a second whatever the requests.
pub struct Interfaces {
    listed: Mutex<(Instant, Vec<IpAddr>)>,
}

/// How long a listing is trusted for an address not in it.
const RELIST: Duration = Duration::from_secs(1);

impl Interfaces {
    pub fn new(addresses: Vec<IpAddr>) -> Interfaces {
        Interfaces {
            listed: Mutex::new((Instant::now(), canonical(addresses))),
        }
    }

    /// Whether `ip` is an address of one of this machine's interfaces.
    pub fn contains(&self, ip: IpAddr) -> bool {
        let ip = ip.to_canonical();
        let mut listed = self.listed.lock().unwrap_or_else(|p| p.into_inner());
        if listed.1.contains(&ip) {
            return true;
        }
        if listed.0.elapsed() >= RELIST {
            *listed = (Instant::now(), canonical(addresses()));
            return listed.1.contains(&ip);
        }
        false
    }
}

fn canonical(addresses: Vec<IpAddr>) -> Vec<IpAddr> {
    addresses.into_iter().map(|ip| ip.to_canonical()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loopback_is_listed_and_urls_leave_out_what_others_cannot_reach() {
        let all = addresses();
        assert!(all.iter().any(IpAddr::is_loopback), "{all:?}");
        let some: Vec<IpAddr> = [
            "127.0.0.1",
            "192.0.2.2",
            "fe80::1",
            "169.254.1.1",
            "2001:db8::2",
        ]
        .iter()
        .map(|a| a.parse().unwrap())
        .collect();
        let v4: IpAddr = "192.0.2.2".parse().unwrap();
        let v6: IpAddr = "2001:db8::2".parse().unwrap();
        assert_eq!(urls_for("0.0.0.0".parse().unwrap(), &some), [v4]);
        assert_eq!(urls_for("::".parse().unwrap(), &some), [v4, v6]);
        assert_eq!(urls_for(v6, &some), [v6]);
        assert!(urls_for("::ffff:127.0.0.1".parse().unwrap(), &some).is_empty());
        let known = Interfaces::new(some);
        assert!(known.contains("::ffff:192.0.2.2".parse().unwrap()));
        assert!(!known.contains("203.0.113.9".parse().unwrap()));
    }
}
