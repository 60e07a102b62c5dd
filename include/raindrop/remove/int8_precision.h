#pragma once
// Whether this CPU's int8 matrix products saturate in ONNX Runtime, so that quantized graphs
// must be run through its exact (slower) kernels.
//
// The int8 model folders multiply uint8 activations by int8 weights. On x86, ONNX Runtime sums
// each pair of such products with VPMADDUBSW, in saturating 16-bit arithmetic (255 * 127 * 2
// = 64,770 is clamped to 32,767), unless the CPU has VNNI (AVX512-VNNI or AVX-VNNI), whose
// instructions sum in 32 bits. On a CPU without VNNI (AMD Zen 2 and 3, Intel before Ice Lake
// and Alder Lake) the clamp changed our int8 detector's probabilities by up to 1.0 and halved
// the drops it found on a real photograph (docs/RESULTS.md 3.8). Session option
// "session.x64quantprecision" makes ONNX Runtime use its unsaturated uint8 x uint8 kernels
// instead; their integer sums are exact, so the outputs equal a VNNI CPU's bit for bit. On a
// VNNI CPU the option would only slow the graphs down, so it is set only where needed.
// Float graphs are unaffected either way.

namespace raindrop::removal {

// True on an x86 CPU without usable VNNI (instruction present and enabled by the OS); false
// on a VNNI CPU and on every other architecture (ARM's int8 dot products sum in 32 bits).
bool int8_products_saturate();

// True on an x86 CPU with usable VNNI: where int8 graphs run faster than float ones (1.2-1.3x
// for the default's, docs/RESULTS.md 4.60), so that models/DEFAULT's int8 copy is chosen
// (model_paths.h). False elsewhere: without VNNI the exact kernels make int8 slower than float,
// and on other architectures it was never measured.
bool int8_runs_fast();

// What int8 graphs run on here, for --version: "VNNI", "exact uint8 kernels (this CPU has no
// VNNI)", or "32-bit sums" (not x86).
const char* int8_kernels_description();

}  // namespace raindrop::removal
