#include <stdio.h>
#include "frep.h"
int main(void) { puts(FREP_VERSION_STRING); return 0; }
