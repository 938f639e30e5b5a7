% van der Pol for three values of mu, one ode45 call each
mus = [0.5 1 2];
y0 = [2; 0];
figure; hold on
for k = 1:length(mus)
    mu = mus(k);
    [t, y] = ode45(@(t,y) vdp_mu(t, y, mu), [0 10], y0);
    plot(t, y(:,1))
end
legend('\mu = 0.5', '\mu = 1', '\mu = 2')

function dydt = vdp_mu(t, y, mu)
dydt = [y(2); mu*(1 - y(1)^2)*y(2) - y(1)];
end
