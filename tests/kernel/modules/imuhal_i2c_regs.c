// SPDX-License-Identifier: GPL-2.0
/*
 * imuhal test adapter: a full I2C adapter for the kernel tests.
 *
 * The kernel's i2c-stub offers only SMBus transfers (no I2C_FUNC_I2C, so the I2C_RDWR ioctl
 * fails with EOPNOTSUPP). This adapter offers plain I2C messages, so I2C_RDWR works, and
 * SMBus through the core's emulation. Each address given in "addrs" acknowledges and holds a
 * 256-byte register file with a register pointer, like most sensor chips: a write message
 * sets the pointer from its first byte and stores the following bytes at the incrementing
 * pointer; a read message returns bytes from the incrementing pointer (wrapping at 0xff).
 * A combined write-then-read (repeated start) therefore reads registers. Any other address
 * gets no acknowledge: -ENXIO, as Documentation/i2c/fault-codes.rst asks of adapters.
 * Registers are loaded from user space through the adapter itself (/dev/i2c-N).
 */
#include <linux/i2c.h>
#include <linux/module.h>
#include <linux/mutex.h>

#define MAX_CHIPS 8

static unsigned short addrs[MAX_CHIPS];
static int n_addrs;
module_param_array(addrs, ushort, &n_addrs, 0444);
MODULE_PARM_DESC(addrs, "7-bit addresses that acknowledge (up to 8)");

struct regfile {
	u8 regs[256];
	u8 pointer;
};

static struct regfile chips[MAX_CHIPS];
static DEFINE_MUTEX(chips_lock);

static struct regfile *find_chip(u16 addr)
{
	int i;

	for (i = 0; i < n_addrs; i++)
		if (addrs[i] == addr)
			return &chips[i];
	return NULL;
}

static int regs_xfer(struct i2c_adapter *adap, struct i2c_msg *msgs, int num)
{
	int i, j;

	mutex_lock(&chips_lock);
	for (i = 0; i < num; i++) {
		struct i2c_msg *m = &msgs[i];
		struct regfile *chip = (m->flags & I2C_M_TEN) ? NULL : find_chip(m->addr);

		if (!chip) {
			mutex_unlock(&chips_lock);
			return -ENXIO;
		}
		if (m->flags & I2C_M_RD) {
			for (j = 0; j < m->len; j++)
				m->buf[j] = chip->regs[chip->pointer++];
		} else if (m->len) {
			chip->pointer = m->buf[0];
			for (j = 1; j < m->len; j++)
				chip->regs[chip->pointer++] = m->buf[j];
		}
	}
	mutex_unlock(&chips_lock);
	return num;
}

static u32 regs_func(struct i2c_adapter *adap)
{
	return I2C_FUNC_I2C | I2C_FUNC_SMBUS_EMUL;
}

static const struct i2c_algorithm regs_algorithm = {
	.master_xfer = regs_xfer,
	.functionality = regs_func,
};

static struct i2c_adapter regs_adapter = {
	.owner = THIS_MODULE,
	.class = I2C_CLASS_HWMON,
	.algo = &regs_algorithm,
	.name = "imuhal register-file adapter",
};

static int __init regs_init(void)
{
	if (n_addrs == 0) {
		pr_err("imuhal_i2c_regs: give the addresses that answer, e.g. addrs=0x68,0x1e\n");
		return -EINVAL;
	}
	return i2c_add_adapter(&regs_adapter);
}

static void __exit regs_exit(void)
{
	i2c_del_adapter(&regs_adapter);
}

module_init(regs_init);
module_exit(regs_exit);
MODULE_DESCRIPTION("imuhal test adapter: full I2C with register-file chips");
MODULE_LICENSE("GPL");
