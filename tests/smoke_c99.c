#define KDRT_IMPLEMENTATION
#include "kdrt.h"
int main(void) { return 0; }
