/* kdrt's implementation for the tools' programs, compiled once as C99 (tests bring their own). */
#define KDRT_IMPLEMENTATION
#include "kdrt.h"
