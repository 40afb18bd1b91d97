// prtbake/engine.h: renamed prtbake/ibl.h (the engine packages' header); this forwarding
// header is kept for one release.
#pragma once

#include "prtbake/ibl.h"
