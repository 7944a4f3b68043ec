// The one place that chooses the MLP kernel variant (mlp_kernel.hpp) for this CPU.
#include "t1rt/mlp_kernel.hpp"

namespace t1rt::mlp_kernel {

const Variant& portable_variant() {
  static const Variant v{"portable", &portable::forward};
  return v;
}

const Variant& selected_variant() {
  static const Variant& v = []() -> const Variant& {
#if defined(T1RT_MLP_AVX2_FMA)
    static const Variant avx2{"avx2+fma", &avx2_fma::forward};
    __builtin_cpu_init();  // may run before the CPU model is initialised (static constructors)
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) return avx2;
#endif
    return portable_variant();
  }();
  return v;
}

}  // namespace t1rt::mlp_kernel
