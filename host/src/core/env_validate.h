// Private: the texel checks of validateEnvironment (envmap.h), for loaders that see an
// environment a part at a time.
#pragma once

#include <string>

#include "prtbake/envmap.h"
#include "prtbake/error.h"

namespace prtbake::detail {

struct InvalidTexels {
  long long values = 0;     // NaN, Inf or negative values
  long long nonFinite = 0;  // of which NaN or Inf
};

// Counts the invalid values of env's texels (replacing them by 0 when `clamp`); throws
// InputError naming env.source when the pixel data does not match the size.
InvalidTexels countInvalidTexels(EnvMap& env, bool clamp);

// The error for invalid values found without the clamp option.
InputError invalidTexelsError(const std::string& source, const InvalidTexels& bad);

}  // namespace prtbake::detail
