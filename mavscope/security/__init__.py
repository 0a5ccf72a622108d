"""The security layer: key material, signature verification with replay state, payload ciphers, the
X25519 key exchange, the pipeline stage that gives every frame its verdicts, and the audits.

The core (framing, dissection) knows nothing of keys: `stage.SecurityStage` runs after the dissector
(added by `pipeline.session`) and sets `Frame.security` with `frame._replace`.
Secrets never leave this package in text: key objects print as their name only.
"""
