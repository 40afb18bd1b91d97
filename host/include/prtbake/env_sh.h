// prtbake/env_sh.h: renamed prtbake/env.h (the environment product's header); this
// forwarding header is kept for one release.
#pragma once

#include "prtbake/env.h"
