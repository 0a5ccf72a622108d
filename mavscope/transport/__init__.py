"""Transport layer: link headers, IPv4/IPv6, UDP and reassembled TCP, down to MAVLink-bearing bytes."""
