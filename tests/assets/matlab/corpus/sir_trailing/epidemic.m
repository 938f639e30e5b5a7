% epidemic with trailing parameters passed through ode45
clear all
clc
close all

weeks = [0 30];
S0 = 2e5; I0 = 50; R0 = 0;
y0 = [S0 I0 R0];
a = 4.1e-6;
b = 0.6;
options = odeset;
[t,y] = ode45(@sir3,weeks,y0,options,a,b);

figure(1)
plot(t,y(:,1),'b',t,y(:,2),'r',t,y(:,3),'g')
xlabel('t (weeks)')
legend('S(t)','I(t)','R(t)')

[peak,where] = max(y(:,2));
tpeak = t(where);
peak
for i = 1:length(t)
    if y(i,2) > 0.5*peak
        break;
    end
end
