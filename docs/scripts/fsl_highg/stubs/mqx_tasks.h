/* Stub for the harness: the MQX-Lite task header, reduced to the one global the fusion code
   touches (ProjectGlobals, fields as in the library's mqx_tasks.h). */
#ifndef MQX_TASKS_H
#define MQX_TASKS_H
#include "build.h"
struct ProjectGlobals
{
	uint8 AngularVelocityPacketOn;
	uint8 DebugPacketOn;
	uint8 RPCPacketOn;
	uint8 AltPacketOn;
	quaternion_type QuaternionPacketType;
	quaternion_type DefaultQuaternionPacketType;
	int16 MagneticPacketID;
	uint8 iPacketNumber;
	int8 iMPL3115Found;
	int32 loopcounter;
};
extern struct ProjectGlobals globals;
#endif
