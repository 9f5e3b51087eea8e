/* Harness that produced tests/data/filters/fsl_highg_{9dof_gby,6dof_gy}_kalman.csv: the public
 * Freescale sensor fusion library (memsindustrygroup/Open-Source-Sensor-Fusion, build 422,
 * commit b4a502a, Sources/fusion.c, orientation.c, matrix.c, approximations.c, magnetic.c;
 * build.h with THISCOORDSYSTEM set to NED, nothing else changed), driven as its tasks.c does.
 *
 *   harness COUNTS.csv OUT_9DOF.csv OUT_6DOF.csv
 *
 * Per fast row (200 Hz, SENSORFS): the int16 counts go into the sensor structures exactly as
 * RdSensData_Run leaves them after the HAL (the input is already in the NED build's sensor
 * frame), summed; every OVERSAMPLE_RATIO (8) rows the fast and averaged readings are formed as
 * RdSensData_Run does, the magnetometer calibration is applied (fInvertMagCal) and
 * fRun_6DOF_GY_KALMAN and fRun_9DOF_GBY_KALMAN run, as in Fusion_Run. Differences from the
 * firmware, on purpose: the magnetic calibration is forced valid (V = 0, invW = I, B = 50 uT,
 * 4B^2 = 1e4) instead of being fitted from a buffer, and no calibration task runs. Both
 * filters start with resetflag set (Fusion_Init): their first call only initialises, the
 * second locks to the eCompass (9DOF) or the accelerometer tilt (6DOF).
 *
 * Output: one row per Kalman call; kf_valid is 0 for the initialising call. mag_jam repeats
 * the library's own test (fusion.c, "set the magnetic jamming flag"), since the flag is a
 * local variable of fRun_9DOF_GBY_KALMAN: |dErrSe+|^2 > 4B^2 with a valid calibration.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "include_all.h"

struct ProjectGlobals globals;

struct AccelSensor thisAccel;
struct MagSensor thisMag;
struct GyroSensor thisGyro;
struct MagCalibration thisMagCal;
struct SV_6DOF_GY_KALMAN thisSV_6DOF_GY_KALMAN;
struct SV_9DOF_GBY_KALMAN thisSV_9DOF_GBY_KALMAN;

static const char *COMMON_9 =
	"# outputs of fRun_9DOF_GBY_KALMAN on fsl_highg_counts.csv, one row per Kalman step (idx: "
	"the fast row that completed it)\n";
static const char *COMMON_6 =
	"# outputs of fRun_6DOF_GY_KALMAN on fsl_highg_counts.csv, one row per Kalman step (idx: "
	"the fast row that completed it)\n";
static const char *PRODUCED =
	"# produced by the public reference memsindustrygroup/Open-Source-Sensor-Fusion "
	"Sources/fusion.c build 422 (commit b4a502a), NED build (THISCOORDSYSTEM patched from "
	"ANDROID), float32 x86-64, driven as tasks.c does: SENSORFS 200, OVERSAMPLE_RATIO 8 (Kalman "
	"at 25 Hz on the newest fast accel/mag sample and the 8 buffered gyro samples), magnetic "
	"calibration forced valid (V = 0, invW = I, B = 50 uT, 4B^2 = 1e4), filter reset at the "
	"slice start (the first call only initialises, the second locks to eCompass / "
	"accelerometer tilt)\n";
static const char *UNITS =
	"# quaternion scalar first, sensor (body NED) -> NED; Euler: Freescale NED angles, yaw "
	"0..360; gbias deg/s\n";

int main(int argc, char **argv)
{
	FILE *in, *out9, *out6;
	char line[4096], t_s[32];
	int idx, c[9], i, counter = 0, kf = 0;
	int8 valid6, valid9, jam;
	float ftmp;

	if (argc != 4)
	{
		fprintf(stderr, "usage: %s COUNTS.csv OUT_9DOF.csv OUT_6DOF.csv\n", argv[0]);
		return 2;
	}
	in = fopen(argv[1], "r");
	out9 = fopen(argv[2], "w");
	out6 = fopen(argv[3], "w");
	if (!in || !out9 || !out6)
	{
		perror("harness");
		return 2;
	}
	fputs(COMMON_9, out9); fputs(PRODUCED, out9); fputs(UNITS, out9);
	fputs(COMMON_6, out6); fputs(PRODUCED, out6); fputs(UNITS, out6);
	fputs("kf_idx,idx,t_s,kf_valid,q0,q1,q2,q3,roll_deg,pitch_deg,yaw_deg,"
	      "gbias_x_dps,gbias_y_dps,gbias_z_dps,incl_deg,mag_jam\n", out9);
	fputs("kf_idx,idx,t_s,kf_valid,q0,q1,q2,q3,roll_deg,pitch_deg,yaw_deg,"
	      "gbias_x_dps,gbias_y_dps,gbias_z_dps\n", out6);

	/* the inputs' scales: 1/2048 g, 1/16 uT, 1/128 deg/s per count */
	thisAccel.fgPerCount = 1.0F / 2048.0F;
	thisMag.fuTPerCount = 1.0F / 16.0F;
	thisMag.fCountsPeruT = 16.0F;
	thisGyro.fDegPerSecPerCount = 1.0F / 128.0F;

	/* magnetic calibration forced valid */
	memset(&thisMagCal, 0, sizeof thisMagCal);
	for (i = X; i <= Z; i++)
		thisMagCal.finvW[i][i] = 1.0F;
	thisMagCal.fB = DEFAULTB;
	thisMagCal.fFourBsq = 4.0F * DEFAULTB * DEFAULTB;
	thisMagCal.iValidMagCal = 4;

	/* Fusion_Init */
	globals.DefaultQuaternionPacketType = Q3;
	globals.loopcounter = 0;
	thisSV_6DOF_GY_KALMAN.resetflag = true;
	thisSV_9DOF_GBY_KALMAN.resetflag = true;

	while (fgets(line, sizeof line, in))
	{
		if (line[0] == '#' || line[0] == 'i')
			continue; /* comments and the header row */
		if (sscanf(line, "%d,%31[^,],%d,%d,%d,%d,%d,%d,%d,%d,%d", &idx, t_s, &c[0], &c[1], &c[2],
			   &c[3], &c[4], &c[5], &c[6], &c[7], &c[8]) != 11)
		{
			fprintf(stderr, "harness: cannot parse: %s", line);
			return 1;
		}
		/* RdSensData_Run: HAL-aligned fast readings, summed */
		for (i = X; i <= Z; i++)
		{
			thisAccel.iGpFast[i] = (int16) c[i];
			thisGyro.iYpFast[counter][i] = (int16) c[3 + i];
			thisMag.iBpFast[i] = (int16) c[6 + i];
			thisAccel.iSumGpFast[i] += (int32) thisAccel.iGpFast[i];
			thisMag.iSumBpFast[i] += (int32) thisMag.iBpFast[i];
			thisGyro.iSumYpFast[i] += (int32) thisGyro.iYpFast[counter][i];
		}
		if (++counter < OVERSAMPLE_RATIO)
			continue;
		for (i = X; i <= Z; i++)
		{
			thisAccel.fGpFast[i] = (float) thisAccel.iGpFast[i] * thisAccel.fgPerCount;
			thisAccel.iGp[i] = (int16)(thisAccel.iSumGpFast[i] / OVERSAMPLE_RATIO);
			thisAccel.fGp[i] = (float) thisAccel.iSumGpFast[i] * thisAccel.fgPerCount / (float) OVERSAMPLE_RATIO;
			thisMag.fBpFast[i] = (float) thisMag.iBpFast[i] * thisMag.fuTPerCount;
			thisMag.iBp[i] = (int16)(thisMag.iSumBpFast[i] / OVERSAMPLE_RATIO);
			thisMag.fBp[i] = (float) thisMag.iSumBpFast[i] * thisMag.fuTPerCount / (float) OVERSAMPLE_RATIO;
			thisGyro.iYp[i] = (int16)(thisGyro.iSumYpFast[i] / OVERSAMPLE_RATIO);
			thisGyro.fYp[i] = (float) thisGyro.iSumYpFast[i] * thisGyro.fDegPerSecPerCount / (float) OVERSAMPLE_RATIO;
			thisAccel.iSumGpFast[i] = 0;
			thisMag.iSumBpFast[i] = 0;
			thisGyro.iSumYpFast[i] = 0;
		}
		counter = 0;

		/* Fusion_Run */
		fInvertMagCal(&thisMag, &thisMagCal);
		valid6 = !thisSV_6DOF_GY_KALMAN.resetflag;
		valid9 = !thisSV_9DOF_GBY_KALMAN.resetflag;
		fRun_6DOF_GY_KALMAN(&thisSV_6DOF_GY_KALMAN, &thisAccel, &thisGyro, THISCOORDSYSTEM, OVERSAMPLE_RATIO);
		fRun_9DOF_GBY_KALMAN(&thisSV_9DOF_GBY_KALMAN, &thisAccel, &thisMag, &thisGyro, &thisMagCal,
				     THISCOORDSYSTEM, OVERSAMPLE_RATIO);
		globals.loopcounter++;

		ftmp = thisSV_9DOF_GBY_KALMAN.fdErrSePl[X] * thisSV_9DOF_GBY_KALMAN.fdErrSePl[X] +
		       thisSV_9DOF_GBY_KALMAN.fdErrSePl[Y] * thisSV_9DOF_GBY_KALMAN.fdErrSePl[Y] +
		       thisSV_9DOF_GBY_KALMAN.fdErrSePl[Z] * thisSV_9DOF_GBY_KALMAN.fdErrSePl[Z];
		jam = valid9 && (thisMagCal.iValidMagCal) && (ftmp > thisMagCal.fFourBsq);

		fprintf(out9, "%d,%d,%s,%d,%.9g,%.9g,%.9g,%.9g,%.5f,%.5f,%.5f,%.6g,%.6g,%.6g,%.5f,%d\n",
			kf, idx, t_s, valid9,
			thisSV_9DOF_GBY_KALMAN.fqPl.q0, thisSV_9DOF_GBY_KALMAN.fqPl.q1,
			thisSV_9DOF_GBY_KALMAN.fqPl.q2, thisSV_9DOF_GBY_KALMAN.fqPl.q3,
			thisSV_9DOF_GBY_KALMAN.fPhiPl, thisSV_9DOF_GBY_KALMAN.fThePl,
			thisSV_9DOF_GBY_KALMAN.fPsiPl,
			thisSV_9DOF_GBY_KALMAN.fbPl[X], thisSV_9DOF_GBY_KALMAN.fbPl[Y],
			thisSV_9DOF_GBY_KALMAN.fbPl[Z], thisSV_9DOF_GBY_KALMAN.fDeltaPl, jam);
		fprintf(out6, "%d,%d,%s,%d,%.9g,%.9g,%.9g,%.9g,%.5f,%.5f,%.5f,%.6g,%.6g,%.6g\n",
			kf, idx, t_s, valid6,
			thisSV_6DOF_GY_KALMAN.fqPl.q0, thisSV_6DOF_GY_KALMAN.fqPl.q1,
			thisSV_6DOF_GY_KALMAN.fqPl.q2, thisSV_6DOF_GY_KALMAN.fqPl.q3,
			thisSV_6DOF_GY_KALMAN.fPhiPl, thisSV_6DOF_GY_KALMAN.fThePl,
			thisSV_6DOF_GY_KALMAN.fPsiPl,
			thisSV_6DOF_GY_KALMAN.fbPl[X], thisSV_6DOF_GY_KALMAN.fbPl[Y],
			thisSV_6DOF_GY_KALMAN.fbPl[Z]);
		kf++;
	}
	fclose(in);
	fclose(out9);
	fclose(out6);
	return 0;
}
