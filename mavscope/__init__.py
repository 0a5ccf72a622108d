"""mavscope: Wireshark-style packet analysis and forensics for MAVLink."""

__version__ = "0.1.0"
