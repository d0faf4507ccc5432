#!/usr/bin/env bash
# Regenerates tests/data/recordings/: short recordings of real struck objects (bells, a
# cowbell, an agogo) cut from Debian's hydrogen-drumkits package (GPL-2 and CC-BY-SA-3.0
# kits; see tests/data/recordings/README.md). Not a test dependency: the clips are committed.
set -euo pipefail
cd "$(dirname "$0")/.."
out=tests/data/recordings
work=target/recordings
mkdir -p "$work" "$out"
if [ ! -d "$work/x" ]; then
    apt-get update -qq
    (cd "$work" && apt-get download hydrogen-drumkits)
    dpkg-deb -x "$work"/hydrogen-drumkits_*.deb "$work/x"
fi
kits="$work/x/usr/share/hydrogen/data/drumkits"
cp "$work/x/usr/share/doc/hydrogen-drumkits/copyright" "$out/hydrogen-drumkits.copyright"
# name, source, seconds kept (the whole clip when shorter)
python3 - "$kits" "$out" <<'PY'
import sys, wave
kits, out = sys.argv[1], sys.argv[2]
clips = [
    ("cowbell.wav", "The Black Pearl 1.0/Cowbell-Hard.wav", 1.0),
    ("paiste-bell.wav", "The Black Pearl 1.0/PaisteBell-Hard.wav", 1.0),
    ("kenkeni-bell.wav", "circAfrique v4/Kenkeni1 Bell Hit.wav", 1.0),
    ("agogo-high.wav", "ForzeeStereo/AgogoHigh-3.wav", 1.0),
]
for name, src, seconds in clips:
    with wave.open(f"{kits}/{src}", "rb") as r:
        params = r.getparams()
        frames = r.readframes(min(r.getnframes(), int(seconds * r.getframerate())))
    with wave.open(f"{out}/{name}", "wb") as w:
        w.setparams(params)
        w.writeframes(frames)
    print(name, params.nchannels, "ch", params.sampwidth * 8, "bit", params.framerate, "Hz")
PY
