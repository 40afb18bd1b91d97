// constants.h (internal): the mathematical constants of the library, written once.
#pragma once

namespace prtbake {

inline constexpr double kPi = 3.14159265358979323846;

}  // namespace prtbake
