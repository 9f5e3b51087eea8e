/* Stub for the harness: Processor Expert's Events.h (interrupt handlers), not needed to run
   the fusion code on a PC. */
#ifndef EVENTS_H
#define EVENTS_H
#endif
