"""The pipeline: capture records become MAVLink frames (`dissect`), then every later stage the options ask
for is added in data-path order (`session`). `options` holds what a front end may ask of it."""
