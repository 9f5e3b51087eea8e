// SPDX-License-Identifier: GPL-2.0
/*
 * imuhal test controller: an SPI controller whose one device is a chip's register file,
 * bound to spidev so that user space reaches it as /dev/spidevB.0.
 *
 * No SPI controller in the kernel works without hardware (spi-loopback-test needs a wired
 * controller; QEMU's x86 machines have none), so this one answers like a sensor with the
 * common SPI register protocol (MPU-9250, MAX21100, ...): within one message (one chip-select
 * assertion) the first byte is the register address, bit 7 set for a read; the following
 * bytes read (or, bit 7 clear, write) registers at the incrementing address. The address
 * bits are "addr_mask" (default 0x7f) and wrap within it. The byte clocked out during the
 * address phase reads 0x00.
 *
 * The register map (addr_mask + 1 bytes) is loaded from and read back by user space through
 * the binary sysfs attribute "registers" of the platform device imuhal-spi-regs:
 * /sys/devices/platform/imuhal-spi-regs/registers.
 */
#include <linux/module.h>
#include <linux/mutex.h>
#include <linux/platform_device.h>
#include <linux/spi/spi.h>
#include <linux/sysfs.h>

#define MAP_SIZE 256

static unsigned int addr_mask = 0x7f;
module_param(addr_mask, uint, 0444);
MODULE_PARM_DESC(addr_mask, "register address bits of the first byte (default 0x7f)");

static u8 registers[MAP_SIZE];
static DEFINE_MUTEX(registers_lock);
static struct platform_device *pdev;
static struct spi_controller *ctlr;

static int regs_transfer_one_message(struct spi_controller *c, struct spi_message *msg)
{
	struct spi_transfer *t;
	bool address_phase = true, read = false;
	unsigned int address = 0, i;

	mutex_lock(&registers_lock);
	list_for_each_entry(t, &msg->transfers, transfer_list) {
		const u8 *tx = t->tx_buf;
		u8 *rx = t->rx_buf;

		for (i = 0; i < t->len; i++) {
			u8 in = tx ? tx[i] : 0, out = 0;

			if (address_phase) {
				read = in & 0x80;
				address = in & addr_mask;
				address_phase = false;
			} else if (read) {
				out = registers[address];
				address = (address + 1) & addr_mask;
			} else {
				registers[address] = in;
				address = (address + 1) & addr_mask;
			}
			if (rx)
				rx[i] = out;
		}
		msg->actual_length += t->len;
	}
	mutex_unlock(&registers_lock);
	msg->status = 0;
	spi_finalize_current_message(c);
	return 0;
}

static ssize_t registers_read(struct file *file, struct kobject *kobj,
			      struct bin_attribute *attr, char *buf, loff_t off, size_t count)
{
	mutex_lock(&registers_lock);
	memcpy(buf, registers + off, count);
	mutex_unlock(&registers_lock);
	return count;
}

static ssize_t registers_write(struct file *file, struct kobject *kobj,
			       struct bin_attribute *attr, char *buf, loff_t off, size_t count)
{
	mutex_lock(&registers_lock);
	memcpy(registers + off, buf, count);
	mutex_unlock(&registers_lock);
	return count;
}

static BIN_ATTR_RW(registers, MAP_SIZE);

static struct spi_board_info chip_info = {
	/* an id in spidev's own table ("spidev" itself is refused) */
	.modalias = "dh2228fv",
	.max_speed_hz = 10000000,
	.chip_select = 0,
	.mode = SPI_MODE_3,
};

static int __init regs_init(void)
{
	int ret;

	if (addr_mask == 0 || addr_mask >= MAP_SIZE)
		return -EINVAL;
	pdev = platform_device_register_simple("imuhal-spi-regs", -1, NULL, 0);
	if (IS_ERR(pdev))
		return PTR_ERR(pdev);
	ret = device_create_bin_file(&pdev->dev, &bin_attr_registers);
	if (ret)
		goto err_pdev;
	ctlr = spi_alloc_master(&pdev->dev, 0);
	if (!ctlr) {
		ret = -ENOMEM;
		goto err_attr;
	}
	ctlr->bus_num = -1;
	ctlr->num_chipselect = 1;
	ctlr->mode_bits = SPI_CPOL | SPI_CPHA | SPI_CS_HIGH;
	ctlr->bits_per_word_mask = SPI_BPW_MASK(8);
	ctlr->transfer_one_message = regs_transfer_one_message;
	ret = spi_register_controller(ctlr);
	if (ret) {
		spi_controller_put(ctlr);
		goto err_attr;
	}
	if (!spi_new_device(ctlr, &chip_info)) {
		ret = -ENODEV;
		spi_unregister_controller(ctlr);
		goto err_attr;
	}
	return 0;

err_attr:
	device_remove_bin_file(&pdev->dev, &bin_attr_registers);
err_pdev:
	platform_device_unregister(pdev);
	return ret;
}

static void __exit regs_exit(void)
{
	spi_unregister_controller(ctlr);
	device_remove_bin_file(&pdev->dev, &bin_attr_registers);
	platform_device_unregister(pdev);
}

module_init(regs_init);
module_exit(regs_exit);
MODULE_DESCRIPTION("imuhal test controller: SPI register file behind spidev");
MODULE_LICENSE("GPL");
