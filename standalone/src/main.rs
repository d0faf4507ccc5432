//! ModalForge without a DAW: the plugin and its editor window on JACK or ALSA audio and MIDI
//! (nice-plug's standalone wrapper). `modalforge-standalone --help` lists the audio options;
//! `--backend dummy` runs without a sound card (the screenshot script uses it).

fn main() {
    if !nice_plug::nice_export_standalone::<modalforge_plugin::ModalForge>() {
        std::process::exit(1);
    }
}
