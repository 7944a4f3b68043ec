// The hidden-layer activations of a policy artifact. Its own header, free of Eigen, because the MLP kernel
// (mlp_kernel.hpp) is compiled once per instruction set and must not see Eigen's inline code.
#pragma once

namespace t1rt {

enum class Activation { kSwish, kElu, kTanh, kRelu };

}  // namespace t1rt
