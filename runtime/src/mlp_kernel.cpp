// The MLP forward kernel (mlp_kernel.hpp). runtime/CMakeLists.txt compiles this file once per variant:
// T1RT_MLP_VARIANT names the namespace of each copy and the flags differ (baseline x86-64, or -mavx2 -mfma).
// Copies built with different flags must never share a symbol the linker could pick from the wrong one, so
// only forward() has external linkage, everything else is internal, and the file calls C library functions
// (math.h) rather than C++ inline wrappers; a ctest checks the AVX2 object for weak symbols.
#include <math.h>

#include "t1rt/mlp_kernel.hpp"

#ifndef T1RT_MLP_VARIANT
#error "compile mlp_kernel.cpp with -DT1RT_MLP_VARIANT=<namespace> (runtime/CMakeLists.txt)"
#endif

namespace t1rt::mlp_kernel::T1RT_MLP_VARIANT {

namespace {
// One vector register of floats for the flags this copy is built with (wider types are split into scalar code
// where the registers are narrower).
#if defined(__AVX__)
constexpr int kLanes = 8;
#else
constexpr int kLanes = 4;
#endif
typedef float Vec __attribute__((vector_size(kLanes * sizeof(float))));
constexpr int kVecs = kPanelRows / kLanes;
static_assert(kPanelRows % kLanes == 0, "a panel is a whole number of vectors");

// exp_vec's constants (Cephes expf): ln 2 split so n * kLn2Hi is exact, the polynomial highest power first.
constexpr float kExpMaxArg = 88.3762626647949f, kExpMinArg = -87.3365447504019f;
constexpr float kLog2e = 1.44269504088896341f, kLn2Hi = 0.693359375f, kLn2Lo = -2.12194440e-4f;
constexpr float kRoundMagic = 12582912.0f;  // 1.5 * 2^23: adding it rounds to an integer in the mantissa
constexpr int kExpPolyTerms = 6;
constexpr float kExpPoly[kExpPolyTerms] = {1.9875691500e-4f, 1.3981999507e-3f, 8.3334519073e-3f,
                                           4.1665795894e-2f, 1.6666665459e-1f, 5.0000001201e-1f};
constexpr int kFloatExponentBias = 127, kFloatMantissaBits = 23;

inline Vec load(const float* p) {
  Vec v;
  __builtin_memcpy(&v, p, sizeof v);
  return v;
}

inline void store(float* p, Vec v) { __builtin_memcpy(p, &v, sizeof v); }

// y = bias + W x over one panel. Two sets of sums (even and odd inputs) keep enough independent
// multiply-adds in flight to hide their latency; the weights are read once, front to back.
void panel(const float* w, const float* bias, const float* x, int cols, float* y) {
  Vec even[kVecs], odd[kVecs];
  for (int v = 0; v < kVecs; ++v) {
    even[v] = load(bias + v * kLanes);
    odd[v] = Vec{};
  }
  int j = 0;
  for (; j + 1 < cols; j += 2, w += 2 * kPanelRows) {
    const float x0 = x[j], x1 = x[j + 1];
    for (int v = 0; v < kVecs; ++v) {
      even[v] += load(w + v * kLanes) * x0;
      odd[v] += load(w + kPanelRows + v * kLanes) * x1;
    }
  }
  if (j < cols)
    for (int v = 0; v < kVecs; ++v) even[v] += load(w + v * kLanes) * x[j];
  for (int v = 0; v < kVecs; ++v) store(y + v * kLanes, even[v] + odd[v]);
}

typedef int IVec __attribute__((vector_size(kLanes * sizeof(int))));

// e^x, x clamped to where e^x is a finite normal float: Cephes' expf (range reduction by ln 2 in two parts, a
// degree-5 polynomial, the power of two built in the exponent bits), about 1 ulp from e^x, on whole vectors.
Vec exp_vec(Vec x) {
  x = x > kExpMaxArg ? kExpMaxArg : x;  // a NaN fails both tests and passes through
  x = x < kExpMinArg ? kExpMinArg : x;
  Vec n = x * kLog2e + kRoundMagic;  // round to nearest: the integer lands in the low bits
  const IVec bits = (IVec)n - (IVec)(Vec{} + kRoundMagic);
  n -= kRoundMagic;
  const Vec r = x - n * kLn2Hi - n * kLn2Lo;
  Vec p = Vec{} + kExpPoly[0];
  for (int i = 1; i < kExpPolyTerms; ++i) p = p * r + kExpPoly[i];
  p = p * (r * r) + r + 1.0f;
  return p * (Vec)((bits + kFloatExponentBias) << kFloatMantissaBits);
}

// tanh(x) = 1 - 2 / (e^2x + 1); exp_vec's clamps give exactly +-1 far out, and a NaN passes through.
Vec tanh_vec(Vec x) { return 1.0f - 2.0f / (exp_vec(x + x) + 1.0f); }

// Hidden-layer activation, in place, over n values (a whole number of vectors).
void activate(Activation activation, float* h, int n) {
  switch (activation) {
    case Activation::kSwish:  // x * sigmoid(x) = x / (1 + e^-x)
      for (int i = 0; i < n; i += kLanes) {
        const Vec x = load(h + i);
        store(h + i, x / (1.0f + exp_vec(-x)));
      }
      break;
    case Activation::kElu:
      for (int i = 0; i < n; ++i) h[i] = h[i] > 0.0f ? h[i] : expm1f(h[i]);
      break;
    case Activation::kTanh:
      for (int i = 0; i < n; ++i) h[i] = tanhf(h[i]);
      break;
    case Activation::kRelu:
      for (int i = 0; i < n; ++i) h[i] = h[i] > 0.0f ? h[i] : 0.0f;
      break;
  }
}
}  // namespace

void forward(const Net& net, const float* input, float* const* outputs) {
  const float* x = input;
  for (int i = 0; i < net.num_layers; ++i) {
    const PackedLayer& l = net.layers[i];
    float* y = outputs[i];
    const bool hidden = i + 1 < net.num_layers;
    for (int r = 0; r < l.rows; r += kPanelRows) {
      panel(l.panels + r * l.cols, l.bias + r, x, l.cols, y + r);
      // Panel by panel: the activation's arithmetic overlaps the next panel's weight loads.
      if (hidden) activate(net.activation, y + r, kPanelRows);
      else if (net.tanh_output)
        for (int v = 0; v < kPanelRows; v += kLanes) store(y + r + v, tanh_vec(load(y + r + v)));
    }
    x = y;
  }
}

}  // namespace t1rt::mlp_kernel::T1RT_MLP_VARIANT
