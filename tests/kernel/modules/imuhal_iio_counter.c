// SPDX-License-Identifier: GPL-2.0
/*
 * imuhal test IIO device "imuhal-counter": a three-axis accelerometer whose scans count.
 *
 * The kernel's iio_simple_dummy exports one accelerometer axis and constant values, so a
 * reader cannot tell a lost scan from a kept one. This device exports in_accel_{x,y,z}_raw
 * with a shared scale and offset and a triggered buffer with the soft timestamp, and every
 * trigger makes one scan: x is the scan's number (s16, wrapping), y its negation, z a
 * constant 1 g (16284 + offset 100 = 16384 counts at 9.80665/16384 m/s^2 per count). A
 * scan the buffer had no room for still takes its number, so a reader sees exactly how many
 * were lost. The timestamp is taken in the trigger's top half (iio_pollfunc_store_time),
 * with the clock chosen in current_timestamp_clock. It has no trigger of its own: use an
 * hrtimer or sysfs trigger.
 */
#include <linux/iio/buffer.h>
#include <linux/iio/iio.h>
#include <linux/iio/trigger_consumer.h>
#include <linux/iio/triggered_buffer.h>
#include <linux/module.h>
#include <linux/mutex.h>
#include <linux/platform_device.h>

#define Z_RAW 16284
#define OFFSET 100
#define SCALE_NANO 598550 /* 9.80665 / 16384 m/s^2 per count */

enum { SCAN_X, SCAN_Y, SCAN_Z, SCAN_TIMESTAMP };

#define ACCEL_CHANNEL(axis, index) {						\
	.type = IIO_ACCEL,							\
	.modified = 1,								\
	.channel2 = IIO_MOD_##axis,						\
	.info_mask_separate = BIT(IIO_CHAN_INFO_RAW),				\
	.info_mask_shared_by_type = BIT(IIO_CHAN_INFO_SCALE) |			\
				    BIT(IIO_CHAN_INFO_OFFSET),			\
	.scan_index = index,							\
	.scan_type = {								\
		.sign = 's',							\
		.realbits = 16,							\
		.storagebits = 16,						\
		.endianness = IIO_LE,						\
	},									\
}

static const struct iio_chan_spec counter_channels[] = {
	ACCEL_CHANNEL(X, SCAN_X),
	ACCEL_CHANNEL(Y, SCAN_Y),
	ACCEL_CHANNEL(Z, SCAN_Z),
	IIO_CHAN_SOFT_TIMESTAMP(SCAN_TIMESTAMP),
};

struct counter_state {
	struct mutex lock;
	u32 scans;
};

static s16 axis_value(int index, u32 scans)
{
	switch (index) {
	case SCAN_X:
		return (s16)scans;
	case SCAN_Y:
		return (s16)(0 - scans);
	default:
		return Z_RAW;
	}
}

static int counter_read_raw(struct iio_dev *indio_dev, struct iio_chan_spec const *chan,
			    int *val, int *val2, long mask)
{
	struct counter_state *st = iio_priv(indio_dev);

	switch (mask) {
	case IIO_CHAN_INFO_RAW:
		mutex_lock(&st->lock);
		*val = axis_value(chan->scan_index, st->scans);
		mutex_unlock(&st->lock);
		return IIO_VAL_INT;
	case IIO_CHAN_INFO_SCALE:
		*val = 0;
		*val2 = SCALE_NANO;
		return IIO_VAL_INT_PLUS_NANO;
	case IIO_CHAN_INFO_OFFSET:
		*val = OFFSET;
		return IIO_VAL_INT;
	}
	return -EINVAL;
}

static irqreturn_t counter_trigger_handler(int irq, void *p)
{
	struct iio_poll_func *pf = p;
	struct iio_dev *indio_dev = pf->indio_dev;
	struct counter_state *st = iio_priv(indio_dev);
	struct {
		s16 values[SCAN_TIMESTAMP];
		s64 timestamp __aligned(8);
	} scan;
	int bit, i = 0;

	memset(&scan, 0, sizeof(scan));
	mutex_lock(&st->lock);
	st->scans++;
	for_each_set_bit(bit, indio_dev->active_scan_mask, indio_dev->masklength)
		if (bit < SCAN_TIMESTAMP)
			scan.values[i++] = axis_value(bit, st->scans);
	mutex_unlock(&st->lock);
	iio_push_to_buffers_with_timestamp(indio_dev, &scan, pf->timestamp);
	iio_trigger_notify_done(indio_dev->trig);
	return IRQ_HANDLED;
}

static const struct iio_info counter_info = {
	.read_raw = counter_read_raw,
};

static struct platform_device *pdev;

/*
 * The IIO device belongs to a bound platform driver (devm-managed), so a test can remove it
 * while it is being read, as a hot-unplugged or unbound device is removed:
 * echo imuhal-counter > /sys/bus/platform/drivers/imuhal-counter/unbind (and bind to bring
 * it back, under a new iio:deviceN).
 */
static int counter_probe(struct platform_device *platform)
{
	struct iio_dev *indio_dev;
	struct counter_state *st;
	int ret;

	indio_dev = devm_iio_device_alloc(&platform->dev, sizeof(*st));
	if (!indio_dev)
		return -ENOMEM;
	st = iio_priv(indio_dev);
	mutex_init(&st->lock);
	indio_dev->name = "imuhal-counter";
	indio_dev->info = &counter_info;
	indio_dev->channels = counter_channels;
	indio_dev->num_channels = ARRAY_SIZE(counter_channels);
	indio_dev->modes = INDIO_DIRECT_MODE;
	ret = devm_iio_triggered_buffer_setup(&platform->dev, indio_dev, iio_pollfunc_store_time,
					      counter_trigger_handler, NULL);
	if (ret)
		return ret;
	return devm_iio_device_register(&platform->dev, indio_dev);
}

static struct platform_driver counter_driver = {
	.probe = counter_probe,
	.driver = {
		.name = "imuhal-counter",
	},
};

static int __init counter_init(void)
{
	int ret;

	ret = platform_driver_register(&counter_driver);
	if (ret)
		return ret;
	pdev = platform_device_register_simple("imuhal-counter", -1, NULL, 0);
	if (IS_ERR(pdev)) {
		platform_driver_unregister(&counter_driver);
		return PTR_ERR(pdev);
	}
	return 0;
}

static void __exit counter_exit(void)
{
	platform_device_unregister(pdev);
	platform_driver_unregister(&counter_driver);
}

module_init(counter_init);
module_exit(counter_exit);
MODULE_DESCRIPTION("imuhal test IIO device: an accelerometer whose scans count");
MODULE_LICENSE("GPL");
