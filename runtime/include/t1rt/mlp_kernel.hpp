// The dense-MLP forward pass behind a plain C++ interface: no Eigen type and no inline code crosses it.
// src/mlp_kernel.cpp is compiled once per instruction-set variant (runtime/CMakeLists.txt), each copy in its
// own namespace; selected_variant() (src/mlp_dispatch.cpp) picks the best one this CPU runs, once.
#pragma once
#include "t1rt/activation.hpp"

namespace t1rt::mlp_kernel {

// Outputs per weight panel: the block of sums a kernel keeps in registers while it streams the inputs.
inline constexpr int kPanelRows = 32;

inline constexpr int padded_rows(int rows) { return (rows + kPanelRows - 1) / kPanelRows * kPanelRows; }

// One dense layer with its weights packed for a single sequential pass: panel p holds, input after input,
// the kPanelRows weights of outputs [p * kPanelRows, (p + 1) * kPanelRows); rows past `rows` are zero.
struct PackedLayer {
  const float* panels = nullptr;  // padded_rows(rows) * cols values
  const float* bias = nullptr;    // padded_rows(rows) values, zero-padded
  int rows = 0, cols = 0;
};

struct Net {
  const PackedLayer* layers = nullptr;
  int num_layers = 0;
  Activation activation = Activation::kSwish;  // after every layer but the last
  bool tanh_output = false;                    // tanh on the last layer (the tanh_normal output rule), else linear
};

// outputs[i] receives layer i's padded_rows(rows) values; input holds layers[0].cols values. No allocation.
using ForwardFn = void (*)(const Net& net, const float* input, float* const* outputs);

namespace portable {
void forward(const Net& net, const float* input, float* const* outputs);
}
namespace avx2_fma {  // compiled with -mavx2 -mfma; only called where the CPU has both
void forward(const Net& net, const float* input, float* const* outputs);
}

struct Variant {
  const char* name;
  ForwardFn forward;
};

const Variant& portable_variant();  // runs on every CPU this build targets
const Variant& selected_variant();  // the fastest one this CPU runs (decided on first call)

}  // namespace t1rt::mlp_kernel
