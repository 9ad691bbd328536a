/* The one translation unit that holds kdrt's implementation for the test suite. */
#define KDRT_IMPLEMENTATION
#include "kdrt.h"
