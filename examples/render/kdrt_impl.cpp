// kdrt's implementation, compiled once for kdrt-render, its tests and the kdrt_support code they
// link (which expects its user to provide it).
#define KDRT_IMPLEMENTATION
#include "kdrt.h"
